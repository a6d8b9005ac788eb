//! Instances as the renderer sees them after commit.

use std::sync::Arc;

use glam::{Affine3A, Mat3, Mat4};
use openrt_accel::{Aabb, Ray};

use crate::object::ObjectGeometry;
use crate::{CoreError, InstanceId, ObjectId};

/// An instance in a committed scene.
#[derive(Debug, Clone)]
pub struct InstanceRecord {
    /// The API handle.
    pub id: InstanceId,
    /// The instanced object.
    pub object: ObjectId,
    /// The object's geometry at commit time.
    pub geometry: Arc<ObjectGeometry>,
    /// Object to world.
    pub to_world: Affine3A,
    /// World to object.
    pub to_object: Affine3A,
    /// Inverse transpose of the linear part: maps object-space normals to world space.
    pub normal_matrix: Mat3,
    /// Sign of the determinant of the linear part (-1 for mirroring
    /// transforms): geometric normals computed from the winding are
    /// multiplied by it so they follow the transformed winding.
    pub det_sign: f32,
    /// World bounds (the object's bounds transformed).
    pub world_bounds: Aabb,
    /// `true` when the transform is the identity (no ray transform needed).
    pub identity: bool,
}

impl InstanceRecord {
    pub(crate) fn new(id: InstanceId, object: ObjectId, geometry: Arc<ObjectGeometry>, m: Affine3A) -> Self {
        // The inverse is computed in f64 and rounded once: an f32 inverse of
        // an ill-conditioned transform is off by cond * 2^-24 relative, which
        // made rays miss squashed objects (see tests/conditioning.rs).
        let to_object = Affine3A::from_cols_array(
            &glam::DAffine3::from_cols_array(&m.to_cols_array().map(f64::from))
                .inverse()
                .to_cols_array()
                .map(|x| x as f32),
        );
        let lin = Mat3::from(m.matrix3);
        let det_sign = lin.determinant().signum();
        // The inverse's linear part is the linear part's inverse: no second inversion.
        let normal_matrix = Mat3::from(to_object.matrix3).transpose();
        let b = geometry.tree.bounds();
        let world_bounds = if b.is_empty() {
            Aabb::EMPTY
        } else {
            (0..8)
                .fold(Aabb::EMPTY, |acc, i| acc.grow(m.transform_point3(b.corner(i))))
                // Transformed corners carry rounding; widen so the box holds the geometry.
                .enlarged_ulps(4)
        };
        Self {
            id,
            object,
            geometry,
            to_world: m,
            to_object,
            normal_matrix,
            det_sign,
            world_bounds,
            identity: m == Affine3A::IDENTITY,
        }
    }

    /// The ray in object space. The direction is not renormalised, so `t`
    /// means the same in both spaces.
    #[inline]
    #[must_use]
    pub fn ray_to_object(&self, ray: &Ray, t_max: f32) -> Ray {
        if self.identity {
            return ray.with_interval(ray.t_min, t_max);
        }
        Ray::new(
            self.to_object.transform_point3(ray.origin),
            self.to_object.transform_vector3(ray.dir),
            ray.t_min,
            t_max,
        )
    }
}

/// Smallest accepted `|det| / longest column^3` of an instance transform's
/// linear part (1 for rotations and uniform scales; `s` for a squash of one
/// axis by `s`).
///
/// Rays go to object space, and a squashed object is seen there at grazing
/// angles from far away, where the watertight test's conservative `t > 0`
/// bound grows with the conditioning. Measured with rays aimed at the
/// centres of squashed triangles (tests/conditioning.rs): at 1e-4, 2% of them
/// missed; at 1e-3, 0.1%; from 3e-3 on, none. The limit leaves a margin.
pub const MIN_TRANSFORM_CONDITIONING: f32 = 1e-2;

/// Checks that `m` is a finite, affine, invertible instance transform.
pub(crate) fn check_transform(call: &'static str, m: &Mat4) -> Result<Affine3A, CoreError> {
    if !m.is_finite() {
        return Err(CoreError::NonFinite {
            call,
            what: format!("matrix {m}"),
        });
    }
    let row = m.row(3);
    if row != glam::Vec4::new(0.0, 0.0, 0.0, 1.0) {
        return Err(CoreError::NotAffine {
            call,
            row: row.to_array(),
        });
    }
    let lin = Mat3::from_mat4(*m);
    let det = lin.determinant();
    // Scale-invariant conditioning test: |det| against the cube of the
    // longest column. Uniform scales of any size pass.
    let longest = lin.x_axis.length().max(lin.y_axis.length()).max(lin.z_axis.length());
    let conditioning = det.abs() / (longest * longest * longest);
    // NOTE: a NaN conditioning is refused too.
    let conditioned = conditioning >= MIN_TRANSFORM_CONDITIONING;
    if det == 0.0 || !det.is_finite() || !conditioned {
        return Err(CoreError::SingularTransform {
            call,
            det,
            conditioning,
        });
    }
    Ok(Affine3A::from_mat4(*m))
}

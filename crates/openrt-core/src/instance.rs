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
        let to_object = m.inverse();
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
    // longest column. Uniform scales of any size pass; a transform that
    // squashes one axis by more than 1e6 relative to the longest is singular
    // for f32 ray transforms.
    let longest = lin.x_axis.length().max(lin.y_axis.length()).max(lin.z_axis.length());
    if det == 0.0 || !det.is_finite() || det.abs() <= 1e-6 * longest * longest * longest {
        return Err(CoreError::SingularTransform { call, det });
    }
    Ok(Affine3A::from_mat4(*m))
}

//! Deforming glTF meshes: morph targets blended by their weights, then
//! linear blend skinning by the skin's joints (glTF 2.0 specification,
//! sections 3.7.2.2 "Morph Targets" and 3.7.3 "Skins"). Both run per
//! vertex in parallel on the context's pool; the result redefines the
//! node's own object every frame (the paper's unstructured motion: the
//! redefined object gets the fast builder, or a refit of its last tree).

use std::sync::Arc;

use glam::{Mat3, Mat4, Vec2, Vec3};
use openrt_core::{Context, CoreError, MaterialId, ObjectId, PrimitiveKind, VertexArrays};
use rayon::prelude::*;

/// The most joints one vertex may name (`JOINTS_0` and `JOINTS_1`).
pub const GLTF_MAX_INFLUENCES: usize = 8;

/// Vertices per parallel task when deforming.
const CHUNK: usize = 4096;

/// One vertex's joints and weights (unused slots weigh zero).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Influences {
    pub joints: [u16; GLTF_MAX_INFLUENCES],
    pub weights: [f32; GLTF_MAX_INFLUENCES],
}

/// One morph target's displacements.
#[derive(Clone, Debug, Default)]
pub(crate) struct Target {
    pub positions: Option<Vec<Vec3>>,
    pub normals: Option<Vec<Vec3>>,
}

/// A mesh primitive as read: its vertices, the indices that make whole
/// triangles, its material, skin influences and morph targets.
#[derive(Clone, Debug)]
pub(crate) struct Prim {
    pub at: String,
    pub kind: PrimitiveKind,
    pub positions: Vec<Vec3>,
    pub normals: Option<Vec<Vec3>>,
    pub uvs: Option<Vec<Vec2>>,
    pub indices: Vec<u32>,
    pub material: MaterialId,
    pub influences: Option<Vec<Influences>>,
    pub targets: Vec<Target>,
}

/// A skin: its joints (node indices) and their inverse bind matrices.
#[derive(Clone, Debug)]
pub(crate) struct Skin {
    pub joints: Vec<usize>,
    pub inverse_bind: Vec<Mat4>,
}

/// A node whose mesh is deformed: its own object, the mesh's primitives,
/// its skin, and whether its joints or weights are animated (redefined
/// every frame) or not (deformed once, then static).
pub(crate) struct Deformer {
    pub node: usize,
    pub object: ObjectId,
    pub prims: Arc<Vec<Prim>>,
    pub skin: Option<Skin>,
    pub animated: bool,
}

impl Deformer {
    /// The primitives' shapes given every node's world transform and this
    /// node's morph weights.
    pub fn shapes(&self, world: &[Mat4], weights: &[f32]) -> Vec<Shape> {
        let joints: Option<Vec<Mat4>> = self.skin.as_ref().map(|s| {
            s.joints
                .iter()
                .zip(&s.inverse_bind)
                .map(|(&j, ibm)| world[j] * *ibm)
                .collect()
        });
        self.prims
            .iter()
            .map(|p| p.deform(weights, joints.as_deref()))
            .collect()
    }
}

/// A primitive's vertices after deformation.
pub(crate) struct Shape {
    pub positions: Vec<Vec3>,
    pub normals: Option<Vec<Vec3>>,
}

impl Prim {
    /// Positions and normals with the morph `weights` applied, then skinned
    /// by `joints` (each joint's world transform times its inverse bind
    /// matrix) when given. Normals go through the cofactor of the blended
    /// matrix (the inverse transpose up to its determinant) and are
    /// normalized.
    pub fn deform(&self, weights: &[f32], joints: Option<&[Mat4]>) -> Shape {
        let targets: Vec<(f32, &Target)> = self
            .targets
            .iter()
            .zip(weights.iter().copied())
            .filter(|(_, w)| *w != 0.0)
            .map(|(t, w)| (w, t))
            .collect();
        let n = self.positions.len();
        let mut positions = vec![Vec3::ZERO; n];
        let mut normals = self.normals.as_ref().map(|_| vec![Vec3::ZERO; n]);
        let one = |i: usize, p: &mut Vec3, nrm: Option<&mut Vec3>| {
            let mut q = self.positions[i];
            let mut m = self.normals.as_ref().map(|ns| ns[i]);
            for (w, t) in &targets {
                if let Some(d) = &t.positions {
                    q += *w * d[i];
                }
                if let (Some(m), Some(d)) = (m.as_mut(), &t.normals) {
                    *m += *w * d[i];
                }
            }
            if let (Some(joints), Some(inf)) = (joints, &self.influences) {
                let mut blend = Mat4::ZERO;
                for (&j, &w) in inf[i].joints.iter().zip(&inf[i].weights) {
                    if w != 0.0 {
                        blend += joints[usize::from(j)] * w;
                    }
                }
                q = blend.transform_point3(q);
                if let Some(m) = m.as_mut() {
                    *m = cofactor(Mat3::from_mat4(blend)) * *m;
                }
            }
            *p = q;
            if let (Some(out), Some(m)) = (nrm, m) {
                *out = m.normalize_or_zero();
            }
        };
        match normals.as_mut() {
            Some(ns) => positions
                .par_chunks_mut(CHUNK)
                .zip(ns.par_chunks_mut(CHUNK))
                .enumerate()
                .for_each(|(c, (ps, ns))| {
                    for (k, (p, nrm)) in ps.iter_mut().zip(ns.iter_mut()).enumerate() {
                        one(c * CHUNK + k, p, Some(nrm));
                    }
                }),
            None => positions.par_chunks_mut(CHUNK).enumerate().for_each(|(c, ps)| {
                for (k, p) in ps.iter_mut().enumerate() {
                    one(c * CHUNK + k, p, None);
                }
            }),
        }
        Shape { positions, normals }
    }

    /// Triangles the primitive makes.
    pub fn triangles(&self) -> usize {
        match self.kind {
            PrimitiveKind::Triangles => self.indices.len() / 3,
            _ => self.indices.len().saturating_sub(2),
        }
    }

    /// The vertices as read (no deformation).
    pub fn rest(&self) -> Shape {
        Shape {
            positions: self.positions.clone(),
            normals: self.normals.clone(),
        }
    }
}

/// The cofactor matrix: `det(m) * m^-T`, defined for singular matrices too
/// (a joint scaled to zero flattens its normals instead of making them NaN).
fn cofactor(m: Mat3) -> Mat3 {
    Mat3::from_cols(
        m.y_axis.cross(m.z_axis),
        m.z_axis.cross(m.x_axis),
        m.x_axis.cross(m.y_axis),
    )
}

/// Defines `id` from `prims` with their `shapes` (one per primitive), each
/// primitive in one [`Context::draw_elements`] call.
pub(crate) fn define(
    ctx: &mut Context,
    id: ObjectId,
    prims: &[Prim],
    shapes: &[Shape],
) -> Result<(), (String, CoreError)> {
    let mut at = String::new();
    let done = ctx.define_object(id, |ctx| -> Result<(), CoreError> {
        for (prim, shape) in prims.iter().zip(shapes) {
            at.clone_from(&prim.at);
            ctx.material(prim.material)?;
            let arrays = VertexArrays {
                positions: &shape.positions,
                normals: shape.normals.as_deref(),
                uvs: prim.uvs.as_deref(),
            };
            ctx.draw_elements(prim.kind, &arrays, &prim.indices)?;
        }
        Ok(())
    });
    done.map(|_| ()).map_err(|e| (at, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn prim(positions: Vec<Vec3>, normals: Option<Vec<Vec3>>) -> Prim {
        Prim {
            at: "meshes[0].primitives[0]".into(),
            kind: PrimitiveKind::Triangles,
            positions,
            normals,
            uvs: None,
            indices: vec![0, 1, 2],
            material: MaterialId::DEFAULT,
            influences: None,
            targets: Vec::new(),
        }
    }

    #[test]
    fn morph_targets_add_their_weighted_displacements() {
        let mut p = prim(vec![Vec3::ZERO, Vec3::X, Vec3::Y], Some(vec![Vec3::Z; 3]));
        p.targets = vec![
            Target {
                positions: Some(vec![Vec3::Y, Vec3::ZERO, Vec3::ZERO]),
                normals: None,
            },
            Target {
                positions: Some(vec![Vec3::X * 2.0, Vec3::ZERO, Vec3::Z]),
                normals: Some(vec![Vec3::X, Vec3::ZERO, Vec3::ZERO]),
            },
        ];
        let s = p.deform(&[0.5, 0.25], None);
        assert_eq!(
            s.positions,
            vec![Vec3::new(0.5, 0.5, 0.0), Vec3::X, Vec3::new(0.0, 1.0, 0.25)]
        );
        let n0 = s.normals.as_ref().unwrap()[0];
        assert!((n0 - Vec3::new(0.25, 0.0, 1.0).normalize()).length() < 1e-6, "{n0}");
        // Weights beyond the targets are ignored; fewer weights leave the rest at zero.
        assert_eq!(p.deform(&[0.0], None).positions, p.positions);
    }

    #[test]
    fn skinning_blends_joint_matrices_and_keeps_normals_perpendicular() {
        let mut p = prim(
            vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            Some(vec![Vec3::Z, Vec3::Z, Vec3::Z]),
        );
        let half = Influences {
            joints: [0, 1, 0, 0, 0, 0, 0, 0],
            weights: [0.5, 0.5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        };
        let only1 = Influences {
            joints: [1, 0, 0, 0, 0, 0, 0, 0],
            weights: [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        };
        p.influences = Some(vec![
            half,
            only1,
            Influences {
                weights: [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                ..half
            },
        ]);
        let joints = [
            Mat4::from_translation(Vec3::new(0.0, 0.0, 2.0)),
            Mat4::from_scale(Vec3::new(1.0, 3.0, 1.0)) * Mat4::from_rotation_x(0.3),
        ];
        let s = p.deform(&[], Some(&joints));
        let want0 = (joints[0].transform_point3(Vec3::ZERO) + joints[1].transform_point3(Vec3::ZERO)) * 0.5;
        assert!((s.positions[0] - want0).length() < 1e-6);
        assert!((s.positions[1] - joints[1].transform_point3(Vec3::X)).length() < 1e-6);
        assert!((s.positions[2] - Vec3::new(0.0, 1.0, 2.0)).length() < 1e-6);
        // Vertex 1 under a non-uniform scale: its normal stays perpendicular
        // to the transformed tangent plane.
        let n1 = s.normals.as_ref().unwrap()[1];
        for t in [Vec3::X, Vec3::Y] {
            let tt = Mat3::from_mat4(joints[1]) * t;
            assert!(n1.dot(tt).abs() < 1e-6, "{n1} . {tt}");
        }
        assert!((n1.length() - 1.0).abs() < 1e-6);
    }

    #[test]
    fn a_joint_scaled_to_zero_gives_zero_normals_not_nan() {
        let mut p = prim(vec![Vec3::ZERO, Vec3::X, Vec3::Y], Some(vec![Vec3::Z; 3]));
        p.influences = Some(vec![
            Influences {
                joints: [0; 8],
                weights: [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            };
            3
        ]);
        let s = p.deform(&[], Some(&[Mat4::from_scale(Vec3::ZERO)]));
        assert!(s.normals.unwrap().iter().all(|n| *n == Vec3::ZERO));
        assert!(s.positions.iter().all(|q| *q == Vec3::ZERO));
    }

    #[test]
    fn large_meshes_are_deformed_the_same_in_parallel_chunks() {
        let n = CHUNK * 2 + 17;
        let positions: Vec<Vec3> = (0..n).map(|i| Vec3::new(i as f32, 0.5, -1.0)).collect();
        let mut p = prim(positions.clone(), None);
        p.targets = vec![Target {
            positions: Some(vec![Vec3::Y; n]),
            normals: None,
        }];
        let s = p.deform(&[2.0], None);
        for (i, q) in s.positions.iter().enumerate() {
            assert_eq!(*q, positions[i] + Vec3::Y * 2.0, "vertex {i}");
        }
    }
}

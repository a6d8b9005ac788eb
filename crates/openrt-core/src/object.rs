//! Object geometry and its tree.

use std::sync::Arc;

use glam::{Vec2, Vec3};
use openrt_accel::{BuilderKind, KdTree, Triangle};

use crate::MaterialId;

/// Per-triangle shading attributes of an object, in object space.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ShadingData {
    /// Vertex normals per triangle (the geometric normal where none was given).
    pub normals: Vec<[Vec3; 3]>,
    /// Whether triangle `i` had vertex normals.
    pub has_normals: Vec<bool>,
    /// Texture coordinates per triangle (zero where none were given).
    pub uvs: Vec<[Vec2; 3]>,
    /// Material per triangle.
    pub materials: Vec<MaterialId>,
}

/// A finished object definition: triangles plus shading data.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ObjectMesh {
    /// Triangles in object space (degenerate ones already dropped).
    pub triangles: Vec<Triangle>,
    /// Shading attributes, one entry per triangle.
    pub shading: ShadingData,
    /// Degenerate triangles dropped from the definition.
    pub dropped: usize,
}

/// What instances share: an object's kd-tree and its shading data.
#[derive(Debug)]
pub struct ObjectGeometry {
    /// The object kd-tree (owns the triangles).
    pub tree: KdTree,
    /// Shading attributes indexed by `Hit::prim`.
    pub shading: Arc<ShadingData>,
}

impl ObjectGeometry {
    /// Which builder made the tree.
    #[must_use]
    pub fn builder(&self) -> BuilderKind {
        self.tree.stats().builder
    }
}

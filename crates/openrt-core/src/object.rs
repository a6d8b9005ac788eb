//! Object geometry and its tree.

use std::sync::Arc;

use glam::{Vec2, Vec3};
use openrt_accel::{
    Aabb, AccelError, BVH_REFIT_COST_LIMIT, BuilderKind, Bvh, FastParams, Frustum, Hit, KdNode, KdTree, PacketBoxes,
    Ray, Triangle,
};

use crate::MaterialId;
use crate::shading_record::{RecordBin, Records, ShadingRecord};

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

/// The structure built over an object's triangles.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum Accel {
    /// The paper's kd-tree (SAH for static and affine objects, the fast
    /// builder and its refit for unstructured motion).
    Kd,
    /// A wide BVH (binned SAH, 4-wide nodes and an 8-wide copy for single
    /// rays on AVX2; refitted for unstructured motion). The default: its
    /// frames are on par with the kd-trees' within the bench's swings
    /// (behind on the terrain), its shadow queries faster on the museums,
    /// and its refits of moving and deforming meshes several times cheaper
    /// (docs/BENCHMARKS.md).
    #[default]
    Bvh,
}

impl Accel {
    /// Both structures.
    pub const ALL: [Self; 2] = [Self::Kd, Self::Bvh];

    /// The name used by the CLI, RON scenes and the bench (`kd`, `bvh`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Kd => "kd",
            Self::Bvh => "bvh",
        }
    }
}

impl std::str::FromStr for Accel {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "kd" => Ok(Self::Kd),
            "bvh" => Ok(Self::Bvh),
            _ => Err(format!("unknown acceleration structure {s:?}: expected kd or bvh")),
        }
    }
}

/// An object's tree: a kd-tree or a BVH, with the same queries and the
/// same answers (bit for bit: both test the same triangles with the same
/// kernel, and exact ties go to the lower triangle index).
#[derive(Debug)]
pub enum ObjectTree {
    /// A kd-tree.
    Kd(KdTree),
    /// A BVH and the builder it stands for (`Fast`: an unstructured
    /// object's, refitted when redefined).
    Bvh(Bvh, BuilderKind),
}

/// Whether SAH builds of BVH objects (those built once) pre-split their
/// most wasteful triangles (`Bvh::build_presplit`): yes, unless
/// `OPENRT_BVH_PRESPLIT=0` (read once; for measurements side by side).
fn presplit() -> bool {
    static PRESPLIT: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *PRESPLIT.get_or_init(|| std::env::var("OPENRT_BVH_PRESPLIT").as_deref() != Ok("0"))
}

/// Calls the same method on either structure.
macro_rules! both {
    ($self:expr, $t:ident => $e:expr) => {
        match $self {
            ObjectTree::Kd($t) => $e,
            ObjectTree::Bvh($t, _) => $e,
        }
    };
}

impl ObjectTree {
    /// Builds `accel`'s tree with `builder`; `prev`: the object's last tree,
    /// refitted when both it and this build are the fast builder's (and of
    /// the same structure).
    pub fn build(
        accel: Accel,
        tris: Vec<Triangle>,
        builder: BuilderKind,
        prev: Option<&ObjectTree>,
    ) -> Result<Self, AccelError> {
        let fast = builder == BuilderKind::Fast;
        Ok(match (accel, prev) {
            (Accel::Kd, Some(Self::Kd(p))) if fast && p.stats().builder == BuilderKind::Fast => {
                Self::Kd(KdTree::refit_fast(p, tris, &FastParams::default())?)
            }
            (Accel::Kd, _) => Self::Kd(KdTree::build(tris, builder)?),
            (Accel::Bvh, Some(Self::Bvh(p, BuilderKind::Fast))) if fast => {
                Self::Bvh(Bvh::refit(p, tris, BVH_REFIT_COST_LIMIT)?, builder)
            }
            (Accel::Bvh, _) if !fast && presplit() => Self::Bvh(Bvh::build_presplit(tris)?, builder),
            (Accel::Bvh, _) => Self::Bvh(Bvh::build(tris)?, builder),
        })
    }

    /// Which structure this is.
    #[must_use]
    pub fn accel(&self) -> Accel {
        match self {
            Self::Kd(_) => Accel::Kd,
            Self::Bvh(..) => Accel::Bvh,
        }
    }

    /// The builder that made the tree (or that a BVH stands for).
    #[must_use]
    pub fn builder(&self) -> BuilderKind {
        match self {
            Self::Kd(t) => t.stats().builder,
            Self::Bvh(_, b) => *b,
        }
    }

    /// `true` when the tree was refitted from the object's last tree.
    #[must_use]
    pub fn refitted(&self) -> bool {
        match self {
            Self::Kd(t) => t.stats().refitted,
            Self::Bvh(t, _) => t.stats().refitted,
        }
    }

    /// Heap bytes of the structure and its triangles.
    #[must_use]
    pub fn bytes(&self) -> usize {
        match self {
            Self::Kd(t) => t.stats().bytes,
            Self::Bvh(t, _) => t.stats().bytes,
        }
    }

    /// Every non-empty leaf, as the occluder hints name them.
    #[must_use]
    pub fn leaves(&self) -> Vec<KdNode> {
        match self {
            Self::Kd(t) => t
                .nodes()
                .iter()
                .filter(|n| n.is_leaf() && n.prim_count() > 0)
                .copied()
                .collect(),
            Self::Bvh(t, _) => t.leaves(),
        }
    }

    /// The triangles, indexed by `Hit::prim`.
    #[must_use]
    pub fn triangles(&self) -> &[Triangle] {
        both!(self, t => t.triangles())
    }

    /// Bounds of the valid triangles.
    #[must_use]
    pub fn bounds(&self) -> Aabb {
        both!(self, t => t.bounds())
    }

    /// See [`KdTree::intersect_within`].
    #[inline]
    pub fn intersect_within(&self, ray: &Ray, closest: &mut f32) -> Option<Hit> {
        both!(self, t => t.intersect_within(ray, closest))
    }

    /// See [`KdTree::occluded`].
    #[must_use]
    #[inline]
    pub fn occluded(&self, ray: &Ray) -> bool {
        both!(self, t => t.occluded(ray))
    }

    /// See [`KdTree::occluder`].
    #[must_use]
    #[inline]
    pub fn occluder(&self, ray: &Ray) -> Option<KdNode> {
        both!(self, t => t.occluder(ray))
    }

    /// See [`KdTree::leaf_blocks`].
    #[must_use]
    pub fn leaf_blocks(&self, ray: &Ray, leaf: KdNode, margin: f32) -> bool {
        both!(self, t => t.leaf_blocks(ray, leaf, margin))
    }

    /// See [`KdTree::leaf_blocks_packet`].
    #[must_use]
    pub fn leaf_blocks_packet<const N: usize>(&self, rays: &[Ray; N], lanes: u32, leaf: KdNode, margin: f32) -> u32 {
        both!(self, t => t.leaf_blocks_packet(rays, lanes, leaf, margin))
    }

    /// See [`KdTree::intersect_packet_in`].
    #[inline]
    pub fn intersect_packet_in<const N: usize>(
        &self,
        rays: &[Ray; N],
        lanes: u32,
        closest: &mut [f32; N],
        hits: &mut [Option<Hit>; N],
        frustum: Option<&Frustum>,
        laid_out: Option<&PacketBoxes<N>>,
    ) -> u32 {
        both!(self, t => t.intersect_packet_in(rays, lanes, closest, hits, frustum, laid_out))
    }

    /// See [`KdTree::occluder_packet_in`].
    #[must_use]
    #[inline]
    pub fn occluder_packet_in<const N: usize>(
        &self,
        rays: &[Ray; N],
        lanes: u32,
        frustum: Option<&Frustum>,
        laid_out: Option<&PacketBoxes<N>>,
    ) -> (u32, Option<KdNode>) {
        both!(self, t => t.occluder_packet_in(rays, lanes, frustum, laid_out))
    }
}

/// What instances share: an object's tree and its shading data.
#[derive(Debug)]
pub struct ObjectGeometry {
    /// The object's tree (owns the triangles).
    pub tree: ObjectTree,
    /// Each triangle's shading attributes in one cache line, indexed by
    /// `Hit::prim`: what the renderer reads.
    pub(crate) records: Arc<Records>,
    /// [`ShadingData::has_normals`] (the records hold zero normals where it
    /// is `false`).
    has_normals: Arc<Vec<bool>>,
}

impl ObjectGeometry {
    /// `tree` with the shading attributes `shading` (one entry per
    /// triangle of the tree), packed for the renderer; on the pool's threads
    /// when called on a pool and the object is large, in a buffer of `bin`.
    pub(crate) fn new(tree: ObjectTree, shading: &ShadingData, bin: &Arc<RecordBin>) -> Self {
        Self {
            tree,
            records: Arc::new(ShadingRecord::all(shading, bin)),
            has_normals: Arc::new(shading.has_normals.clone()),
        }
    }

    /// Another tree over this geometry's triangles, with its shading
    /// (shared, not copied).
    pub(crate) fn with_tree(&self, tree: ObjectTree) -> Self {
        Self {
            tree,
            records: Arc::clone(&self.records),
            has_normals: Arc::clone(&self.has_normals),
        }
    }

    /// The shading attributes in the API's form, indexed by `Hit::prim`:
    /// the definition's, except that a triangle without vertex normals
    /// lists its geometric normal (the unnormalised edge cross product,
    /// as the API fills it in) whatever the definition held there.
    #[must_use]
    pub fn shading(&self) -> ShadingData {
        ShadingRecord::data(&self.records, &self.has_normals, self.tree.triangles())
    }

    /// Which builder made the tree.
    #[must_use]
    pub fn builder(&self) -> BuilderKind {
        self.tree.builder()
    }
}

//! What an AFF file describes, before it is handed to the API.

use std::collections::HashMap;
use std::path::PathBuf;

use glam::{Mat4, Vec2, Vec3};
use openrt_core::{Camera, Material, PointLight};

use super::keyframes::Track;

/// An `fm` material state plus an optional texture file.
#[derive(Clone, Debug, PartialEq)]
pub struct AffMaterial {
    /// The `fm` parameters (its `texture` is unset: textures are files here).
    pub material: Material,
    /// Index into [`AffScene::textures`].
    pub texture: Option<usize>,
}

/// Triangles with optional per-vertex normals and texture coordinates.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AffMesh {
    /// Vertices.
    pub triangles: Vec<[Vec3; 3]>,
    /// Vertex normals, where given.
    pub normals: Vec<Option<[Vec3; 3]>>,
    /// Texture coordinates, where given.
    pub uvs: Vec<Option<[Vec2; 3]>>,
    /// Material index per triangle.
    pub materials: Vec<usize>,
}

impl AffMesh {
    pub(crate) fn push(&mut self, tri: [Vec3; 3], n: Option<[Vec3; 3]>, uv: Option<[Vec2; 3]>, material: usize) {
        self.triangles.push(tri);
        self.normals.push(n);
        self.uvs.push(uv);
        self.materials.push(material);
    }

    /// Number of triangles.
    #[must_use]
    pub fn len(&self) -> usize {
        self.triangles.len()
    }

    /// `true` without triangles.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }
}

/// One occurrence of an `x name { ... }` block.
#[derive(Clone, Debug, PartialEq)]
pub struct AnimNode {
    /// The name that selects its keyframes.
    pub name: String,
    /// Enclosing animated node, if any.
    pub parent: Option<usize>,
    /// Static transform from this node's frame to the parent's (the `xs`
    /// blocks between them).
    pub to_parent: Mat4,
    /// Geometry directly under this node (not under nested `x` nodes), in its frame.
    pub mesh: AffMesh,
}

/// A `tpa` triangle: vertices and normals sampled at times, linearly
/// interpolated between samples and clamped outside.
#[derive(Clone, Debug, PartialEq)]
pub struct AnimatedTriangle {
    /// Sample times, increasing.
    pub times: Vec<f32>,
    /// Vertices at each sample (already in world space).
    pub vertices: Vec<[Vec3; 3]>,
    /// Normals at each sample (not unit length in the files).
    pub normals: Vec<[Vec3; 3]>,
    /// Material index.
    pub material: usize,
}

impl AnimatedTriangle {
    /// Vertices and normals at `time`.
    #[must_use]
    pub fn at(&self, time: f32) -> ([Vec3; 3], [Vec3; 3]) {
        // Inconsistent lists (possible: the fields are public) are cut to
        // the shortest; an empty triangle has no samples and stays at zero.
        let n = self.times.len().min(self.vertices.len()).min(self.normals.len());
        if n == 0 {
            return ([Vec3::ZERO; 3], [Vec3::ZERO; 3]);
        }
        // NOTE: a NaN time takes the first sample.
        let after_first = time > self.times[0];
        if !after_first || n == 1 {
            return (self.vertices[0], self.normals[0]);
        }
        if time >= self.times[n - 1] {
            return (self.vertices[n - 1], self.normals[n - 1]);
        }
        let i = self.times[..n].windows(2).position(|w| time < w[1]).unwrap_or(n - 2);
        let span = self.times[i + 1] - self.times[i];
        let u = if span > 0.0 { (time - self.times[i]) / span } else { 1.0 };
        let lerp = |a: [Vec3; 3], b: [Vec3; 3]| [a[0].lerp(b[0], u), a[1].lerp(b[1], u), a[2].lerp(b[2], u)];
        (
            lerp(self.vertices[i], self.vertices[i + 1]),
            lerp(self.normals[i], self.normals[i + 1]),
        )
    }
}

/// Counts of what the files contain, includes expanded (checked against
/// `FORMAT-NOTES.md` in tests).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AffCounts {
    /// Triangles of `m` meshes.
    pub mesh_triangles: usize,
    /// `m` commands executed.
    pub mesh_instances: usize,
    /// `p` polygons.
    pub polygons: usize,
    /// `tt` textured triangles.
    pub textured_triangles: usize,
    /// `c` cones.
    pub cones: usize,
    /// `s` spheres.
    pub spheres: usize,
    /// `tpa` triangles.
    pub animated_triangles: usize,
    /// `l` lights.
    pub lights: usize,
    /// `x` blocks met.
    pub animated_node_occurrences: usize,
    /// Distinct `x` names.
    pub animated_node_names: usize,
    /// Degenerate triangles dropped.
    pub degenerate: usize,
}

/// The `a start end frames` animation range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AnimationRange {
    /// First time.
    pub start: f32,
    /// Last time.
    pub end: f32,
    /// Number of frames.
    pub frames: u32,
}

impl AnimationRange {
    /// Time of frame `f` (clamped to the range).
    #[must_use]
    pub fn time(&self, frame: u32) -> f32 {
        if self.frames <= 1 {
            return self.start;
        }
        let f = frame.min(self.frames - 1);
        self.start + (self.end - self.start) * f as f32 / (self.frames - 1) as f32
    }
}

/// A parsed AFF scene.
#[derive(Clone, Debug)]
pub struct AffScene {
    /// Main file.
    pub path: PathBuf,
    /// Static camera from `v`.
    pub camera: Camera,
    /// Image size from `v`.
    pub resolution: (u32, u32),
    /// Background colour.
    pub background: Vec3,
    /// Ambient light.
    pub ambient: Vec3,
    /// Point lights.
    pub lights: Vec<PointLight>,
    /// Animation range.
    pub animation: Option<AnimationRange>,
    /// Materials (distinct `fm` states and textures).
    pub materials: Vec<AffMaterial>,
    /// Texture files.
    pub textures: Vec<PathBuf>,
    /// Geometry outside every `x` node, in world space.
    pub static_mesh: AffMesh,
    /// Animated nodes.
    pub nodes: Vec<AnimNode>,
    /// Triangles with per-vertex animation.
    pub animated: Vec<AnimatedTriangle>,
    /// Keyframes by node name (`camera` animates the view).
    pub tracks: HashMap<String, Track>,
    /// What the files contain.
    pub counts: AffCounts,
    /// What was read leniently (keys that go back in time, dropped).
    pub warnings: Vec<crate::SceneWarning>,
}

impl AffScene {
    /// The camera at `time`: the `k camera` track if there is one (eye =
    /// translation, view = -Z rotated, up = +Y rotated), else the static view.
    #[must_use]
    pub fn camera_at(&self, time: f32) -> Camera {
        let Some(track) = self.tracks.get("camera") else {
            return self.camera;
        };
        let from = super::keyframes::interpolate_vec(&track.translation, time).unwrap_or(self.camera.from);
        let Some(rot) = super::keyframes::interpolate_rot(&track.rotation, time) else {
            return Camera {
                from,
                at: from + (self.camera.at - self.camera.from),
                ..self.camera
            };
        };
        Camera {
            from,
            at: from + rot * Vec3::NEG_Z,
            up: rot * Vec3::Y,
            ..self.camera
        }
    }

    /// Object-to-world transform of node `i` at `time`: its own keyframed
    /// motion under its parents'. `None` for a node that does not exist or
    /// whose parents do not come before it ([`AffScene::validate`]).
    #[must_use]
    pub fn node_transform(&self, i: usize, time: f32) -> Option<Mat4> {
        let mut m = Mat4::IDENTITY;
        let mut at = Some(i);
        let mut below = usize::MAX;
        while let Some(k) = at {
            // Parents come first: a chain that does not go down is broken.
            if k >= below {
                return None;
            }
            let node = self.nodes.get(k)?;
            let own = self.tracks.get(&node.name).map_or(Mat4::IDENTITY, |t| t.matrix(time));
            m = node.to_parent * own * m;
            below = k;
            at = node.parent;
        }
        Some(m)
    }

    /// Checks that every index in the scene points at something: material
    /// and texture indices, node parents (which come before their children),
    /// and the per-triangle lists of meshes and animated triangles. The
    /// parser's scenes always pass; [`super::AffPlayer::new`] checks a scene
    /// built by hand.
    ///
    /// # Errors
    /// [`crate::SceneError::Invalid`] naming the first broken index.
    pub fn validate(&self) -> Result<(), crate::SceneError> {
        let bad = |what: String| {
            Err(crate::SceneError::Invalid {
                path: self.path.clone(),
                what: format!("inconsistent AFF scene: {what}"),
            })
        };
        let nm = self.materials.len();
        if let Some((k, t)) = self
            .materials
            .iter()
            .enumerate()
            .find_map(|(k, m)| m.texture.filter(|&t| t >= self.textures.len()).map(|t| (k, t)))
        {
            return bad(format!("material {k} uses texture {t} of {}", self.textures.len()));
        }
        let mesh_ok = |m: &AffMesh| {
            let n = m.triangles.len();
            m.normals.len() == n && m.uvs.len() == n && m.materials.len() == n && m.materials.iter().all(|&i| i < nm)
        };
        if !mesh_ok(&self.static_mesh) {
            return bad("the static mesh's lists differ in length or use a missing material".into());
        }
        for (k, node) in self.nodes.iter().enumerate() {
            if node.parent.is_some_and(|p| p >= k) {
                return bad(format!(
                    "node {k} ('{}') has parent {:?}, not an earlier node",
                    node.name, node.parent
                ));
            }
            if !mesh_ok(&node.mesh) {
                return bad(format!(
                    "node {k} ('{}'): mesh lists differ in length or use a missing material",
                    node.name
                ));
            }
        }
        for (k, t) in self.animated.iter().enumerate() {
            let n = t.times.len();
            if n == 0 || t.vertices.len() != n || t.normals.len() != n || t.material >= nm {
                return bad(format!(
                    "animated triangle {k}: {n} times, {} vertex and {} normal samples, material {} of {nm}",
                    t.vertices.len(),
                    t.normals.len(),
                    t.material
                ));
            }
        }
        Ok(())
    }
}

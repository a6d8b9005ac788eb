//! The RON scene format (version 1: static scenes).
//!
//! See `docs/SCENE-FORMAT.md` for the reference and an example. Every field
//! except `version`, `objects` and `instances` has a default.

use std::collections::BTreeMap;

use serde::Deserialize;

/// Versions of the format this build reads: 1 (static scenes) and 2 (adds
/// animation, BART wrappers, OBJ files and generators).
pub const SUPPORTED_VERSIONS: &str = "1, 2";

/// A scene file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// Format version (1).
    pub version: u32,
    /// The camera.
    #[serde(default)]
    pub camera: CameraDesc,
    /// Image size the scene is meant for.
    #[serde(default = "default_resolution")]
    pub resolution: (u32, u32),
    /// Background colour.
    #[serde(default)]
    pub background: [f32; 3],
    /// Ambient light.
    #[serde(default = "default_ambient")]
    pub ambient: [f32; 3],
    /// Point lights.
    #[serde(default)]
    pub lights: Vec<LightDesc>,
    /// Texture files by name, relative to the scene file.
    #[serde(default)]
    pub textures: BTreeMap<String, String>,
    /// Materials by name.
    #[serde(default)]
    pub materials: BTreeMap<String, MaterialDesc>,
    /// Objects by name.
    #[serde(default)]
    pub objects: BTreeMap<String, ObjectDesc>,
    /// Instances of the objects.
    #[serde(default)]
    pub instances: Vec<InstanceDesc>,
    /// (v2) Animation time range.
    #[serde(default)]
    pub animation: Option<AnimationDesc>,
    /// (v2) Camera keyframes (Catmull-Rom through the keys).
    #[serde(default)]
    pub camera_keys: Option<CameraKeys>,
    /// (v2) Play a BART AFF scene instead (all other fields must be left out).
    #[serde(default)]
    pub bart: Option<BartDesc>,
    /// (v2) Play a glTF 2.0 file instead (relative to the scene file).
    #[serde(default)]
    pub gltf: Option<GltfDesc>,
    /// (v2) Procedural content added to the scene.
    #[serde(default)]
    pub generators: Vec<GeneratorDesc>,
    /// (v2) The structure under every object: `Bvh` (default) or `Kd`
    /// (the same images; `--accel` overrides it).
    #[serde(default)]
    pub accel: openrt_core::Accel,
    /// (v2) The top level over the instances: `Auto` (default: the BSP,
    /// a BVH from `TOP_LEVEL_BVH_MIN` instances), `Bsp` or `Bvh` (the same
    /// images; `--top-level` overrides it).
    #[serde(default)]
    pub top_level: openrt_core::TopLevel,
}

/// (v2) Animation range: `frames` frames evenly spaced from `start` to `end`.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AnimationDesc {
    /// First time.
    pub start: f32,
    /// Last time.
    pub end: f32,
    /// Number of frames.
    pub frames: u32,
}

/// (v2) Camera keyframes: `(time, (x, y, z))` lists.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CameraKeys {
    /// Eye positions.
    pub from: Vec<(f32, [f32; 3])>,
    /// Look-at points.
    pub at: Vec<(f32, [f32; 3])>,
}

/// (v2) A BART scene, found relative to `OPENRT_BART_DIR`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BartDesc {
    /// AFF file relative to the BART folder, e.g. `"kitchen/kitchen.aff"`.
    pub file: String,
    /// Replace the animated (`tpa`) triangles by this many generated ones
    /// flying in and assembling (museum 4k, 16k, ...).
    #[serde(default)]
    pub animart_triangles: Option<u32>,
    /// Seed of the generated animart.
    #[serde(default)]
    pub seed: u64,
}

/// (v2) A whole glTF scene played through the RON file: its nodes,
/// cameras, lights, materials and animation, as `openrt play file.glb`
/// with these choices.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GltfDesc {
    /// The `.gltf` or `.glb` file, relative to the scene file.
    pub path: String,
    /// `scenes[N]` (default: the file's default scene, else its first).
    #[serde(default)]
    pub scene: Option<usize>,
    /// The animation: an index, a name, `"all"` or `"none"` (default: the first).
    #[serde(default)]
    pub animation: Option<String>,
    /// `cameras[N]` (default: the first perspective camera, else one framing the scene).
    #[serde(default)]
    pub camera: Option<usize>,
}

/// (v2) Procedural content.
#[derive(Debug, Clone, Deserialize)]
pub enum GeneratorDesc {
    /// A heightfield with instanced, swaying trees of two kinds.
    Terrain {
        /// Edge length of the square terrain.
        size: f32,
        /// Cells per edge (2 triangles each).
        grid: u32,
        /// Height amplitude.
        height: f32,
        /// Tree instances.
        trees: u32,
        /// Triangles per tree object.
        tree_triangles: u32,
        /// Tree height.
        tree_size: f32,
        /// Sway amplitude in degrees (0: static trees).
        sway_degrees: f32,
        /// Seed.
        seed: u64,
    },
}

fn default_resolution() -> (u32, u32) {
    (640, 480)
}

fn default_ambient() -> [f32; 3] {
    [0.1; 3]
}

/// Pinhole camera.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CameraDesc {
    /// Eye.
    pub from: [f32; 3],
    /// Look-at point.
    pub at: [f32; 3],
    /// Up vector.
    pub up: [f32; 3],
    /// Vertical field of view in degrees.
    pub fov: f32,
    /// Near distance.
    pub near: f32,
}

impl Default for CameraDesc {
    fn default() -> Self {
        Self {
            from: [0.0, 0.0, 5.0],
            at: [0.0; 3],
            up: [0.0, 1.0, 0.0],
            fov: 45.0,
            near: 0.0,
        }
    }
}

/// A point light.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightDesc {
    /// Position.
    pub position: [f32; 3],
    /// Colour.
    #[serde(default = "white")]
    pub color: [f32; 3],
}

fn white() -> [f32; 3] {
    [1.0; 3]
}

/// A material (NFF/AFF `fm` parameters).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MaterialDesc {
    /// Ambient colour.
    pub ambient: [f32; 3],
    /// Diffuse colour.
    pub diffuse: [f32; 3],
    /// Specular (and mirror) colour.
    pub specular: [f32; 3],
    /// Phong exponent.
    pub shininess: f32,
    /// Emitted colour, added unlit.
    pub emission: [f32; 3],
    /// Transmission.
    pub transmission: f32,
    /// Index of refraction.
    pub ior: f32,
    /// Name of a texture in `textures`.
    pub texture: Option<String>,
    /// Name of a texture in `textures` multiplying `emission`.
    pub emission_texture: Option<String>,
    /// One-sided surface.
    pub one_sided: bool,
}

impl Default for MaterialDesc {
    fn default() -> Self {
        Self {
            ambient: [0.1; 3],
            diffuse: [0.8; 3],
            specular: [0.0; 3],
            shininess: 0.0,
            emission: [0.0; 3],
            transmission: 0.0,
            ior: 1.0,
            texture: None,
            emission_texture: None,
            one_sided: false,
        }
    }
}

/// Geometry of an object.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum ObjectDesc {
    /// An indexed triangle mesh.
    Mesh {
        /// Vertex positions.
        vertices: Vec<[f32; 3]>,
        /// Vertex index triples.
        triangles: Vec<[u32; 3]>,
        /// Optional vertex normals (one per vertex).
        #[serde(default)]
        normals: Option<Vec<[f32; 3]>>,
        /// Optional texture coordinates (one per vertex).
        #[serde(default)]
        uvs: Option<Vec<[f32; 2]>>,
        /// Material name.
        #[serde(default)]
        material: Option<String>,
    },
    /// An axis-aligned box.
    Box {
        /// Lower corner.
        min: [f32; 3],
        /// Upper corner.
        max: [f32; 3],
        /// Material name.
        #[serde(default)]
        material: Option<String>,
    },
    /// A tessellated sphere with smooth normals.
    Sphere {
        /// Centre.
        center: [f32; 3],
        /// Radius.
        radius: f32,
        /// Stacks (slices are twice as many).
        #[serde(default = "default_segments")]
        segments: u32,
        /// Material name.
        #[serde(default)]
        material: Option<String>,
    },
    /// (v2) A mesh whose vertices move (unstructured motion): vertex
    /// positions at key times, linearly interpolated and clamped.
    Morph {
        /// Vertex index triples.
        triangles: Vec<[u32; 3]>,
        /// `(time, vertex positions)`, every list as long as the first.
        keys: Vec<(f32, Vec<[f32; 3]>)>,
        /// Material name.
        #[serde(default)]
        material: Option<String>,
    },
    /// (v2) A Wavefront OBJ file (relative to the scene file), through `tobj`.
    Obj {
        /// The file.
        path: String,
        /// Material name (OBJ materials are not read).
        #[serde(default)]
        material: Option<String>,
    },
    /// (v2) A glTF 2.0 file (`.gltf` or `.glb`, relative to the scene
    /// file): every mesh of one of its scenes, in the file's world space,
    /// as one object with one material (the file's materials are not
    /// used). With an animation the file's nodes, skins and morph weights
    /// play at the scene's time and the object is redefined every frame
    /// (unstructured motion); without one it is the scene at rest, defined
    /// once. Instance keys move it as a whole.
    Gltf {
        /// The file.
        path: String,
        /// Material name.
        #[serde(default)]
        material: Option<String>,
        /// `scenes[N]` of the file (default: its default scene, else its first).
        #[serde(default)]
        scene: Option<usize>,
        /// The animation played: an index, a name, `"all"` or `"none"` (at
        /// rest); default: the file's first.
        #[serde(default)]
        animation: Option<String>,
    },
    /// A planar quad, texture coordinates (0,0), (1,0), (1,1), (0,1) times `uv_scale`.
    Quad {
        /// The four corners in order.
        corners: Vec<[f32; 3]>,
        /// Texture repeat count.
        #[serde(default = "one")]
        uv_scale: f32,
        /// Material name.
        #[serde(default)]
        material: Option<String>,
    },
}

fn default_segments() -> u32 {
    16
}

fn one() -> f32 {
    1.0
}

/// One step of an instance transform, applied in order (OpenGL style:
/// later steps act first on the object).
#[derive(Debug, Clone, Deserialize)]
pub enum TransformOp {
    /// Translation.
    Translate([f32; 3]),
    /// Rotation about an axis, in degrees.
    Rotate([f32; 3], f32),
    /// Scale per axis.
    Scale([f32; 3]),
    /// A column-major 4x4 matrix.
    Matrix([f32; 16]),
}

/// An instance of a named object.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InstanceDesc {
    /// Object name.
    pub object: String,
    /// Transform steps (empty: identity).
    #[serde(default)]
    pub transform: Vec<TransformOp>,
    /// (v2) Keyframed motion applied inside `transform` (affine motion).
    #[serde(default)]
    pub keys: Option<InstanceKeys>,
}

/// (v2) Instance keyframes, Catmull-Rom through the keys; the motion is
/// `transform * translate(t) * rotate(t) * scale(t)`.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct InstanceKeys {
    /// `(time, (x, y, z))`.
    pub translate: Vec<(f32, [f32; 3])>,
    /// `(time, axis, degrees)`: absolute rotations.
    pub rotate: Vec<(f32, [f32; 3], f32)>,
    /// `(time, (x, y, z))`.
    pub scale: Vec<(f32, [f32; 3])>,
}

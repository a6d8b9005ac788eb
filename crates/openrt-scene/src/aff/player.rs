//! Plays an AFF scene through the OpenRT-style API.
//!
//! Structure onto motion classes (Wald, Benthin & Slusallek 2003):
//! - geometry outside every `x` node is merged into one static object (few
//!   large objects, not many small ones);
//! - each `x` node's own geometry becomes an object instanced with the
//!   node's world transform, updated every frame (affine motion); nodes with
//!   identical geometry share one object;
//! - all `tpa` triangles form one object redefined every frame
//!   (unstructured motion).

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{Mat4, Vec3};
use openrt_core::{
    Camera, CommitStats, Context, Environment, InstanceId, Material, MaterialId, ObjectId, PrimitiveKind,
    RenderSettings,
};

use super::model::{AffMesh, AffScene};
use super::parser::parse_aff;
use crate::{SceneError, load_texture};

/// The folder of the BART scenes: `$OPENRT_BART_DIR` when set; otherwise
/// the first of these that exists, whatever the current folder:
/// `shared/bart` beside the repository this crate was built from, beside
/// any folder above the running executable (a `target/` of that
/// repository), and `../shared/bart` from the current folder. When none
/// exists, the first candidate (errors name it).
#[must_use]
pub fn bart_dir() -> PathBuf {
    if let Some(d) = std::env::var_os("OPENRT_BART_DIR") {
        return PathBuf::from(d);
    }
    let candidates = bart_dir_candidates();
    candidates
        .iter()
        .find(|d| d.is_dir())
        .cloned()
        .unwrap_or_else(|| candidates[0].clone())
}

/// Where [`bart_dir`] looks without `OPENRT_BART_DIR`, in order.
#[must_use]
pub fn bart_dir_candidates() -> Vec<PathBuf> {
    let mut c = vec![Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/bart")];
    if let Ok(exe) = std::env::current_exe() {
        c.extend(exe.ancestors().skip(1).map(|a| a.join("../shared/bart")));
    }
    c.push(PathBuf::from("../shared/bart"));
    c
}

/// An AFF scene loaded into a context, ready to step through its frames.
pub struct AffPlayer {
    /// The parsed file (read-only: the player's objects index into it).
    scene: AffScene,
    /// The context the scene lives in.
    pub ctx: Context,
    /// Lights, ambient light and background.
    pub env: Arc<Environment>,
    materials: Vec<MaterialId>,
    node_instances: Vec<Option<InstanceId>>,
    animated_object: Option<ObjectId>,
}

impl AffPlayer {
    /// Parses `path` and defines its objects (nothing is committed yet).
    pub fn load(path: &Path) -> Result<Self, SceneError> {
        let scene = parse_aff(path)?;
        Self::new(scene)
    }

    /// Defines the objects of a parsed scene.
    pub fn new(scene: AffScene) -> Result<Self, SceneError> {
        scene.validate()?;
        let path = scene.path.clone();
        let core = |source| SceneError::Core {
            path: path.clone(),
            source,
        };
        let mut ctx = Context::new();
        let mut textures = Vec::with_capacity(scene.textures.len());
        for t in &scene.textures {
            textures.push(ctx.create_texture(load_texture(t, &path)?));
        }
        let mut materials = Vec::with_capacity(scene.materials.len());
        for m in &scene.materials {
            materials.push(
                ctx.create_material(Material {
                    texture: m.texture.map(|i| textures[i]),
                    ..m.material.clone()
                })
                .map_err(core)?,
            );
        }
        // Static geometry: one object.
        if !scene.static_mesh.is_empty() {
            let id = ctx.gen_object();
            define(&mut ctx, id, &scene.static_mesh, &materials).map_err(core)?;
            ctx.instantiate(id).map_err(core)?;
        }
        // Animated nodes: an object per distinct geometry.
        let mut shared: HashMap<Vec<u32>, ObjectId> = HashMap::new();
        let mut node_instances = Vec::with_capacity(scene.nodes.len());
        for (i, node) in scene.nodes.iter().enumerate() {
            if node.mesh.is_empty() {
                node_instances.push(None);
                continue;
            }
            let key = mesh_key(&node.mesh);
            let id = if let Some(&id) = shared.get(&key) {
                id
            } else {
                let id = ctx.gen_object();
                define(&mut ctx, id, &node.mesh, &materials).map_err(core)?;
                shared.insert(key, id);
                id
            };
            let m = scene
                .node_transform(i, scene.animation.map_or(0.0, |a| a.start))
                .unwrap_or(Mat4::IDENTITY);
            ctx.load_matrix(m).map_err(core)?;
            node_instances.push(Some(ctx.instantiate(id).map_err(core)?));
        }
        ctx.load_identity();
        let animated_object = if scene.animated.is_empty() {
            None
        } else {
            let id = ctx.gen_object();
            define_animated(
                &mut ctx,
                id,
                &scene,
                &materials,
                scene.animation.map_or(0.0, |a| a.start),
            )
            .map_err(core)?;
            ctx.instantiate(id).map_err(core)?;
            Some(id)
        };
        let env = Arc::new(Environment {
            lights: scene.lights.clone(),
            ambient: scene.ambient,
            background: scene.background,
        });
        Ok(Self {
            scene,
            ctx,
            env,
            materials,
            node_instances,
            animated_object,
        })
    }

    /// Instances and objects by motion class: the static mesh, the
    /// instances of animated transform nodes, the redefined triangles.
    #[must_use]
    pub fn motion_classes(&self) -> crate::MotionClasses {
        crate::MotionClasses {
            static_instances: usize::from(!self.scene.static_mesh.is_empty()),
            affine_instances: self.node_instances.iter().flatten().count(),
            deforming_objects: usize::from(self.animated_object.is_some()),
            deforming_triangles: self.scene.animated.len(),
        }
    }

    /// The parsed file.
    #[must_use]
    pub fn scene(&self) -> &AffScene {
        &self.scene
    }

    /// Number of frames (1 for a scene without `a`).
    #[must_use]
    pub fn frames(&self) -> u32 {
        self.scene.animation.map_or(1, |a| a.frames)
    }

    /// Scene time of a frame.
    #[must_use]
    pub fn time_of(&self, frame: u32) -> f32 {
        self.scene.animation.map_or(0.0, |a| a.time(frame))
    }

    /// Moves everything to `time` and commits: node transforms change,
    /// the animated triangles are redefined, nothing else is rebuilt.
    pub fn set_time(&mut self, time: f32) -> Result<CommitStats, SceneError> {
        let path = self.scene.path.clone();
        let core = |source| SceneError::Core {
            path: path.clone(),
            source,
        };
        for (i, inst) in self.node_instances.iter().enumerate() {
            if let Some(inst) = inst {
                let m = self.scene.node_transform(i, time).unwrap_or(Mat4::IDENTITY);
                self.ctx.set_instance_transform(*inst, m).map_err(core)?;
            }
        }
        if let Some(id) = self.animated_object {
            define_animated(&mut self.ctx, id, &self.scene, &self.materials, time).map_err(core)?;
        }
        self.ctx.commit().map_err(core)
    }

    /// The camera at `time`.
    #[must_use]
    pub fn camera(&self, time: f32) -> Camera {
        self.scene.camera_at(time)
    }

    /// The file's resolution with default mode and depth.
    #[must_use]
    pub fn settings(&self) -> RenderSettings {
        RenderSettings {
            width: self.scene.resolution.0,
            height: self.scene.resolution.1,
            ..RenderSettings::default()
        }
    }
}

/// Bit pattern of a mesh, to share objects between nodes with equal geometry.
fn mesh_key(m: &AffMesh) -> Vec<u32> {
    let mut k = Vec::with_capacity(m.len() * 10);
    for (i, t) in m.triangles.iter().enumerate() {
        k.extend(t.iter().flat_map(|v| v.to_array().map(f32::to_bits)));
        k.push(m.materials[i] as u32);
        if let Some(n) = m.normals[i] {
            k.extend(n.iter().flat_map(|v| v.to_array().map(f32::to_bits)));
        }
        if let Some(uv) = m.uvs[i] {
            k.extend(uv.iter().flat_map(|v| v.to_array().map(f32::to_bits)));
        }
    }
    k
}

/// Opens a triangle run with material `m`, closing the previous run when the material changes.
fn material_run(
    ctx: &mut Context,
    current: &mut Option<MaterialId>,
    m: MaterialId,
) -> Result<(), openrt_core::CoreError> {
    if *current != Some(m) {
        if current.is_some() {
            ctx.end()?;
        }
        ctx.material(m)?;
        ctx.begin(PrimitiveKind::Triangles)?;
        *current = Some(m);
    }
    Ok(())
}

fn define(
    ctx: &mut Context,
    id: ObjectId,
    mesh: &AffMesh,
    materials: &[MaterialId],
) -> Result<(), openrt_core::CoreError> {
    ctx.define_object(id, |ctx| define_mesh(ctx, mesh, materials))?;
    Ok(())
}

fn define_mesh(ctx: &mut Context, mesh: &AffMesh, materials: &[MaterialId]) -> Result<(), openrt_core::CoreError> {
    let mut current = None;
    for i in 0..mesh.len() {
        material_run(ctx, &mut current, materials[mesh.materials[i]])?;
        if mesh.normals[i].is_none() {
            ctx.clear_normal()?;
        }
        if mesh.uvs[i].is_none() {
            ctx.clear_tex_coord()?;
        }
        for k in 0..3 {
            if let Some(n) = mesh.normals[i] {
                ctx.normal(n[k])?;
            }
            if let Some(uv) = mesh.uvs[i] {
                ctx.tex_coord(uv[k])?;
            }
            ctx.vertex(mesh.triangles[i][k])?;
        }
    }
    if current.is_some() {
        ctx.end()?;
    }
    Ok(())
}

fn define_animated(
    ctx: &mut Context,
    id: ObjectId,
    scene: &AffScene,
    materials: &[MaterialId],
    time: f32,
) -> Result<(), openrt_core::CoreError> {
    ctx.define_object(id, |ctx| define_animated_mesh(ctx, scene, materials, time))?;
    Ok(())
}

fn define_animated_mesh(
    ctx: &mut Context,
    scene: &AffScene,
    materials: &[MaterialId],
    time: f32,
) -> Result<(), openrt_core::CoreError> {
    let mut current = None;
    for tri in &scene.animated {
        material_run(ctx, &mut current, materials[tri.material])?;
        let (v, n) = tri.at(time);
        if n.contains(&Vec3::ZERO) {
            ctx.clear_normal()?;
        }
        for k in 0..3 {
            if !n.contains(&Vec3::ZERO) {
                ctx.normal(n[k])?;
            }
            ctx.vertex(v[k])?;
        }
    }
    if current.is_some() {
        ctx.end()?;
    }
    Ok(())
}

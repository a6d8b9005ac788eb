//! Turning a RON scene into OpenRT-style API calls.

use std::collections::BTreeMap;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{Mat4, Quat, Vec2, Vec3};
use openrt_core::{
    Camera, CommitStats, Context, CoreError, Environment, InstanceId, Material, MaterialId, ObjectId, PointLight,
    PrimitiveKind, RenderSettings, check_image_size,
};
use rand::{Rng, SeedableRng};

use crate::SceneError;
use crate::aff::{AffPlayer, AnimationRange, RotKey, Tcb, Track, VecKey, interpolate_vec, parse_aff};
use crate::generate::{animart, heightfield, terrain_height, tree};
use crate::limits::{
    MAX_ANIMART_TRIANGLES, MAX_FRAMES, MAX_SCENE_TRIANGLES, MAX_SPHERE_SEGMENTS, MAX_TERRAIN_GRID, MAX_TREE_TRIANGLES,
    MAX_TREES, read_file,
};
use crate::ron_format::{GeneratorDesc, InstanceKeys, ObjectDesc, SUPPORTED_VERSIONS, SceneFile, TransformOp};
use crate::shapes::{emit_box, emit_sphere};
use crate::texture_io::load_texture;

/// A RON scene ready to render: the committed context plus what the file
/// says about viewing and animating it.
pub struct LoadedScene {
    /// The context holding objects and instances (already committed once).
    pub ctx: Context,
    /// The static camera.
    pub camera: Camera,
    /// Lights, ambient and background.
    pub env: Arc<Environment>,
    /// Resolution from the file, default mode and depth.
    pub settings: RenderSettings,
    /// Animation range (v2).
    pub animation: Option<AnimationRange>,
    path: PathBuf,
    camera_from: Vec<VecKey>,
    camera_at: Vec<VecKey>,
    tracked: Vec<(InstanceId, Mat4, Track)>,
    sway: Vec<(InstanceId, Mat4, f32, f32)>,
    morphs: Vec<Morph>,
    gltfs: Vec<GltfObject>,
    warnings: Vec<crate::SceneWarning>,
}

/// A `Gltf` object whose file plays an animation: posed by its own
/// [`GltfPlayer`](crate::GltfPlayer) on the scene's pool and redefined
/// every frame from the posed world-space triangles (unstructured motion).
struct GltfObject {
    id: ObjectId,
    material: MaterialId,
    player: Box<crate::GltfPlayer>,
    /// Triangles the last pose gave.
    triangles: usize,
}

impl GltfObject {
    /// Poses the file at `time` (looping over its animation) and redefines
    /// the object.
    fn define(&mut self, ctx: &mut Context, time: f32) -> Result<(), SceneError> {
        let path = self.player.path().to_path_buf();
        let core = |source| SceneError::Core {
            path: path.clone(),
            source,
        };
        let pool = ctx.pool().map_err(core)?;
        if !self.player.ctx.pool().map_err(core)?.same(&pool) {
            self.player.ctx.set_pool(&pool);
        }
        self.player.set_time(time)?;
        let posed = self.player.ctx.scene();
        self.triangles = posed.instanced_triangles();
        ctx.define_object(self.id, |ctx| {
            ctx.material(self.material)?;
            emit_world_triangles(ctx, &posed)
        })
        .map_err(core)?;
        Ok(())
    }
}

/// An object with vertex keyframes (unstructured motion).
struct Morph {
    id: ObjectId,
    material: MaterialId,
    triangles: Vec<[u32; 3]>,
    keys: Vec<(f32, Vec<Vec3>)>,
}

impl Morph {
    fn vertices_at(&self, time: f32) -> Vec<Vec3> {
        let k = &self.keys;
        if time <= k[0].0 || k.len() == 1 {
            return k[0].1.clone();
        }
        if time >= k[k.len() - 1].0 {
            return k[k.len() - 1].1.clone();
        }
        let i = k.windows(2).position(|w| time < w[1].0).unwrap_or(k.len() - 2);
        let span = k[i + 1].0 - k[i].0;
        let u = if span > 0.0 { (time - k[i].0) / span } else { 1.0 };
        k[i].1.iter().zip(&k[i + 1].1).map(|(a, b)| a.lerp(*b, u)).collect()
    }

    fn define(&self, ctx: &mut Context, time: f32) -> Result<(), CoreError> {
        let v = self.vertices_at(time);
        ctx.define_object(self.id, |ctx| {
            ctx.material(self.material)?;
            ctx.begin(PrimitiveKind::Triangles)?;
            for t in &self.triangles {
                for &i in t {
                    ctx.vertex(v[i as usize])?;
                }
            }
            ctx.end()
        })?;
        Ok(())
    }
}

impl LoadedScene {
    /// What the load accepted leniently: the warnings of the glTF files
    /// its `Gltf` objects read (the RON file itself is read strictly).
    #[must_use]
    pub fn warnings(&self) -> &[crate::SceneWarning] {
        &self.warnings
    }

    /// Instances and objects by motion class: tracked and swaying
    /// instances move affinely, objects with vertex keys deform.
    #[must_use]
    pub fn motion_classes(&self) -> crate::MotionClasses {
        let scene = self.ctx.scene();
        let morphing = |o| self.morphs.iter().any(|m| m.id == o) || self.gltfs.iter().any(|g| g.id == o);
        let mut moving: Vec<InstanceId> = self
            .tracked
            .iter()
            .map(|t| t.0)
            .chain(self.sway.iter().map(|s| s.0))
            .collect();
        moving.sort_unstable();
        moving.dedup();
        crate::MotionClasses {
            static_instances: scene
                .instances()
                .iter()
                .filter(|r| moving.binary_search(&r.id).is_err() && !morphing(r.object))
                .count(),
            affine_instances: moving.len(),
            deforming_objects: self.morphs.len() + self.gltfs.len(),
            deforming_triangles: self.morphs.iter().map(|m| m.triangles.len()).sum::<usize>()
                + self.gltfs.iter().map(|g| g.triangles).sum::<usize>(),
        }
    }

    /// Moves keyframed instances, swaying trees and morphing objects to
    /// `time`, then commits. A static scene only commits.
    pub fn set_time(&mut self, time: f32) -> Result<CommitStats, SceneError> {
        let path = self.path.clone();
        let core = |source| SceneError::Core {
            path: path.clone(),
            source,
        };
        for (id, base, track) in &self.tracked {
            self.ctx
                .set_instance_transform(*id, *base * track.matrix(time))
                .map_err(core)?;
        }
        for (id, base, phase, amp) in &self.sway {
            let a = amp.to_radians() * (std::f32::consts::TAU * 0.5 * time + phase).sin();
            let r = Mat4::from_quat(Quat::from_rotation_z(a) * Quat::from_rotation_x(0.5 * a));
            self.ctx.set_instance_transform(*id, *base * r).map_err(core)?;
        }
        for m in &self.morphs {
            m.define(&mut self.ctx, time).map_err(core)?;
        }
        for g in &mut self.gltfs {
            g.define(&mut self.ctx, time)?;
        }
        self.ctx.commit().map_err(core)
    }

    /// The camera at `time` (keyframes if the file has them).
    #[must_use]
    pub fn camera_at(&self, time: f32) -> Camera {
        let from = interpolate_vec(&self.camera_from, time).unwrap_or(self.camera.from);
        let at = interpolate_vec(&self.camera_at, time).unwrap_or(self.camera.at);
        Camera {
            from,
            at,
            ..self.camera
        }
    }
}

/// Catmull-Rom keys through every listed key (the ends are doubled so the
/// whole range is usable).
fn vec_keys(list: &[(f32, [f32; 3])]) -> Vec<VecKey> {
    let mut keys: Vec<VecKey> = list
        .iter()
        .map(|&(time, v)| VecKey {
            time,
            value: Vec3::from_array(v),
            tcb: Tcb::default(),
        })
        .collect();
    if let (Some(&first), Some(&last)) = (keys.first(), keys.last()) {
        keys.insert(0, first);
        keys.push(last);
    }
    keys
}

fn track(keys: &InstanceKeys) -> Track {
    let mut rotation: Vec<RotKey> = keys
        .rotate
        .iter()
        .map(|&(time, axis, degrees)| RotKey {
            time,
            axis: Vec3::from_array(axis),
            degrees,
            tcb: Tcb::default(),
        })
        .collect();
    if let (Some(&first), Some(&last)) = (rotation.first(), rotation.last()) {
        rotation.insert(0, first);
        rotation.push(last);
    }
    Track {
        translation: vec_keys(&keys.translate),
        rotation,
        scale: vec_keys(&keys.scale),
    }
}

/// Key times must be finite and must not decrease (the AFF rule).
fn check_times(what: &str, times: impl Iterator<Item = f32>) -> Result<(), String> {
    let mut prev = f32::NEG_INFINITY;
    for t in times {
        if !t.is_finite() {
            return Err(format!("{what}: key time {t} is not finite"));
        }
        if t < prev {
            return Err(format!("{what}: key times must not decrease ({t} after {prev})"));
        }
        prev = t;
    }
    Ok(())
}

/// [`check_times`], and finite values.
fn check_vec_keys(what: &str, keys: &[(f32, [f32; 3])]) -> Result<(), String> {
    check_times(what, keys.iter().map(|k| k.0))?;
    match keys.iter().find(|(_, v)| !Vec3::from_array(*v).is_finite()) {
        Some((t, v)) => Err(format!(
            "{what}: the key at time {t} has the value {v:?}, which is not finite"
        )),
        None => Ok(()),
    }
}

/// What a `.ron` file opens as.
pub enum RonScene {
    /// A scene described in the file.
    Scene(Box<LoadedScene>),
    /// A wrapper around a BART scene.
    Bart(Box<AffPlayer>),
    /// A wrapper around a glTF scene.
    Gltf(Box<crate::GltfPlayer>),
}

/// Reads and builds a RON scene file (not a BART wrapper: see [`load_ron_any`]).
pub fn load_ron(path: &Path) -> Result<LoadedScene, SceneError> {
    match load_ron_any(path)? {
        RonScene::Scene(s) => Ok(*s),
        RonScene::Bart(_) | RonScene::Gltf(_) => Err(SceneError::Invalid {
            path: path.to_path_buf(),
            what: "this file wraps a BART or glTF scene: open it with ScenePlayer::open".into(),
        }),
    }
}

/// Reads a RON file: a scene, or a wrapper around a BART scene.
pub fn load_ron_any(path: &Path) -> Result<RonScene, SceneError> {
    let bytes = read_file(path)?;
    let text = String::from_utf8(bytes).map_err(|e| SceneError::Invalid {
        path: path.to_path_buf(),
        what: format!(
            "not UTF-8 text (byte {} is not valid UTF-8)",
            e.utf8_error().valid_up_to()
        ),
    })?;
    let file = parse_ron(&text, path)?;
    if let Some(g) = &file.gltf {
        if file.bart.is_some() || !file.objects.is_empty() || !file.instances.is_empty() || !file.generators.is_empty()
        {
            return Err(SceneError::Invalid {
                path: path.to_path_buf(),
                what:
                    "a glTF wrapper ('gltf') cannot also wrap a BART scene or define objects, instances or generators"
                        .into(),
            });
        }
        let mut player = load_gltf(path, &g.path, g.scene, g.animation.as_deref(), g.camera)?;
        // Objects already built get the scene's structure at the next commit
        // (deforming ones keep theirs: `GLTF_DEFORMING_ACCEL`).
        player.ctx.set_accel(file.accel);
        player.ctx.set_top_level(file.top_level);
        return Ok(RonScene::Gltf(Box::new(player)));
    }
    if let Some(b) = &file.bart {
        if !file.objects.is_empty() || !file.instances.is_empty() || !file.generators.is_empty() {
            return Err(SceneError::Invalid {
                path: path.to_path_buf(),
                what: "a BART wrapper ('bart') cannot also define objects, instances or generators".into(),
            });
        }
        if let Some(n) = b.animart_triangles
            && n > MAX_ANIMART_TRIANGLES
        {
            return Err(SceneError::Invalid {
                path: path.to_path_buf(),
                what: format!(
                    "animart_triangles {n} is beyond the limit of {MAX_ANIMART_TRIANGLES} (MAX_ANIMART_TRIANGLES)"
                ),
            });
        }
        let dir = crate::aff::bart_dir();
        let aff = dir.join(&b.file);
        if !aff.is_file() {
            let how = if std::env::var_os("OPENRT_BART_DIR").is_some() {
                "OPENRT_BART_DIR".to_string()
            } else {
                format!(
                    "the default; also tried {}",
                    crate::aff::bart_dir_candidates()
                        .iter()
                        .map(|p| p.display().to_string())
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            };
            return Err(SceneError::Invalid {
                path: path.to_path_buf(),
                what: format!(
                    "BART file {} not found (BART folder {} from {how}); set OPENRT_BART_DIR to the folder holding kitchen/, museum/ and robots/",
                    aff.display(),
                    dir.display()
                ),
            });
        }
        let mut scene = parse_aff(&aff)?;
        if let Some(n) = b.animart_triangles {
            if scene.materials.is_empty() {
                return Err(SceneError::Invalid {
                    path: aff,
                    what: "no material for the generated animart".into(),
                });
            }
            let material = scene.animated.first().map_or(0, |t| t.material);
            scene.animated = animart(n as usize, b.seed, material);
            scene.counts.animated_triangles = n as usize;
        }
        let mut player = AffPlayer::new(scene)?;
        // Objects already built get the scene's structure at the next commit.
        player.ctx.set_accel(file.accel);
        player.ctx.set_top_level(file.top_level);
        return Ok(RonScene::Bart(Box::new(player)));
    }
    Ok(RonScene::Scene(Box::new(
        Builder {
            path: path.to_path_buf(),
        }
        .build(&file)?,
    )))
}

/// The glTF file `file` (relative to the RON file `ron`) with a RON file's
/// choices of scene, animation (`None`: the first) and camera.
fn load_gltf(
    ron: &Path,
    file: &str,
    scene: Option<usize>,
    animation: Option<&str>,
    camera: Option<usize>,
) -> Result<crate::GltfPlayer, SceneError> {
    let options = crate::GltfOptions {
        scene,
        animation: animation.map_or(crate::GltfAnimation::First, |a| {
            a.parse().unwrap_or(crate::GltfAnimation::First)
        }),
        camera,
    };
    crate::GltfPlayer::load_with(&ron.parent().unwrap_or(Path::new(".")).join(file), &options)
}

fn parse_ron(text: &str, path: &Path) -> Result<SceneFile, SceneError> {
    let file: SceneFile = ron::from_str(text).map_err(|e| SceneError::Parse {
        path: path.to_path_buf(),
        line: e.span.start.line,
        col: e.span.start.col,
        msg: e.code.to_string(),
    })?;
    if file.version != 1 && file.version != 2 {
        return Err(SceneError::Version {
            path: path.to_path_buf(),
            found: file.version,
            supported: SUPPORTED_VERSIONS,
        });
    }
    let v2_only = file.animation.is_some()
        || file.camera_keys.is_some()
        || file.bart.is_some()
        || file.gltf.is_some()
        || !file.generators.is_empty()
        || file.instances.iter().any(|i| i.keys.is_some())
        || file.objects.values().any(|o| {
            matches!(
                o,
                ObjectDesc::Morph { .. } | ObjectDesc::Obj { .. } | ObjectDesc::Gltf { .. }
            )
        });
    if file.version == 1 && v2_only {
        return Err(SceneError::Invalid {
            path: path.to_path_buf(),
            what: "animation, camera keys, BART and glTF wrappers, generators, Morph, Obj and Gltf need 'version: 2'"
                .into(),
        });
    }
    Ok(file)
}

/// Builds a RON scene from text; `path` names it in errors and anchors relative paths.
pub fn load_ron_str(text: &str, path: &Path) -> Result<LoadedScene, SceneError> {
    let file = parse_ron(text, path)?;
    if file.bart.is_some() || file.gltf.is_some() {
        return Err(SceneError::Invalid {
            path: path.to_path_buf(),
            what: "BART and glTF wrappers must be opened from a file".into(),
        });
    }
    Builder {
        path: path.to_path_buf(),
    }
    .build(&file)
}

fn inst_desc_keys(f: &SceneFile, k: usize) -> Option<&InstanceKeys> {
    f.instances[k].keys.as_ref()
}

fn inst_keys(k: Option<&InstanceKeys>) -> Option<InstanceKeys> {
    k.cloned()
}

/// Defines `id` from lists of triangles, one material per list.
fn emit_triangles(
    ctx: &mut Context,
    id: ObjectId,
    parts: &[(MaterialId, Vec<openrt_accel::Triangle>)],
) -> Result<(), CoreError> {
    ctx.begin_object(id)?;
    for (m, tris) in parts {
        ctx.material(*m)?;
        ctx.begin(PrimitiveKind::Triangles)?;
        for t in tris {
            for &v in t {
                ctx.vertex(v)?;
            }
        }
        ctx.end()?;
    }
    ctx.end_object()?;
    Ok(())
}

struct Builder {
    path: PathBuf,
}

/// Resolves an object's material name (`None`: the default material).
type MaterialLookup<'a> = dyn Fn(&Option<String>, &str) -> Result<MaterialId, SceneError> + 'a;

fn v3(a: [f32; 3]) -> Vec3 {
    Vec3::from_array(a)
}

impl Builder {
    fn core(&self) -> impl Fn(CoreError) -> SceneError + '_ {
        |source| SceneError::Core {
            path: self.path.clone(),
            source,
        }
    }

    /// Checks the file's sizes and keys before anything is built: the
    /// resolution against the renderer's image limits, the triangle count
    /// against [`MAX_SCENE_TRIANGLES`], generator and sphere sizes, the
    /// frame count, and keys (finite, times not decreasing, rotation axes
    /// not zero), the same rules as AFF keys.
    fn check_limits(&self, f: &SceneFile) -> Result<(), SceneError> {
        let (w, h) = f.resolution;
        check_image_size("resolution", w, h).map_err(|e| self.invalid(e.to_string()))?;
        if let Some(a) = f.animation
            && a.frames > MAX_FRAMES
        {
            return Err(self.invalid(format!(
                "animation: {} frames is beyond the limit of {MAX_FRAMES} (MAX_FRAMES)",
                a.frames
            )));
        }
        let mut triangles = 0usize;
        for (name, o) in &f.objects {
            triangles = triangles.saturating_add(match o {
                ObjectDesc::Mesh { triangles, .. } | ObjectDesc::Morph { triangles, .. } => triangles.len(),
                ObjectDesc::Box { .. } => 12,
                ObjectDesc::Quad { .. } => 2,
                ObjectDesc::Obj { .. } | ObjectDesc::Gltf { .. } => 0,
                ObjectDesc::Sphere { segments, .. } => {
                    if *segments > MAX_SPHERE_SEGMENTS || *segments < 2 {
                        return Err(self.invalid(format!(
                            "object '{name}': sphere segments {segments} outside 2..={MAX_SPHERE_SEGMENTS} (MAX_SPHERE_SEGMENTS)"
                        )));
                    }
                    4 * (*segments as usize).pow(2)
                }
            });
            if let ObjectDesc::Morph { keys, .. } = o {
                check_times(&format!("object '{name}' keys"), keys.iter().map(|k| k.0)).map_err(|e| self.invalid(e))?;
            }
        }
        for g in &f.generators {
            let GeneratorDesc::Terrain {
                grid,
                trees,
                tree_triangles,
                ..
            } = *g;
            for (what, value, limit) in [
                ("grid", grid, MAX_TERRAIN_GRID),
                ("trees", trees, MAX_TREES),
                ("tree_triangles", tree_triangles, MAX_TREE_TRIANGLES),
            ] {
                if value > limit {
                    return Err(self.invalid(format!("Terrain: {what} {value} is beyond the limit of {limit}")));
                }
            }
            triangles = triangles
                .saturating_add(2 * (grid as usize).pow(2))
                .saturating_add(2 * tree_triangles as usize);
        }
        if triangles > MAX_SCENE_TRIANGLES {
            return Err(self.invalid(format!(
                "{triangles} triangles is beyond the limit of {MAX_SCENE_TRIANGLES} (MAX_SCENE_TRIANGLES)"
            )));
        }
        for (k, inst) in f.instances.iter().enumerate() {
            let Some(keys) = &inst.keys else { continue };
            let what = |list: &str| format!("instance {k} ({}) {list} keys", inst.object);
            check_vec_keys(&what("translate"), &keys.translate).map_err(|e| self.invalid(e))?;
            check_vec_keys(&what("scale"), &keys.scale).map_err(|e| self.invalid(e))?;
            check_times(&what("rotate"), keys.rotate.iter().map(|k| k.0)).map_err(|e| self.invalid(e))?;
            if let Some((t, axis, deg)) = keys
                .rotate
                .iter()
                .find(|(_, axis, deg)| !deg.is_finite() || Vec3::from_array(*axis).try_normalize().is_none())
            {
                return Err(self.invalid(format!(
                    "{}: the key at time {t} has axis {axis:?} and angle {deg}; the axis must be finite and not zero, the angle finite",
                    what("rotate")
                )));
            }
        }
        if let Some(keys) = &f.camera_keys {
            check_vec_keys("camera 'from' keys", &keys.from).map_err(|e| self.invalid(e))?;
            check_vec_keys("camera 'at' keys", &keys.at).map_err(|e| self.invalid(e))?;
        }
        Ok(())
    }

    fn invalid(&self, what: String) -> SceneError {
        SceneError::Invalid {
            path: self.path.clone(),
            what,
        }
    }

    fn build(&self, f: &SceneFile) -> Result<LoadedScene, SceneError> {
        self.check_limits(f)?;
        let mut ctx = Context::new();
        ctx.set_accel(f.accel);
        ctx.set_top_level(f.top_level);
        let dir = self.path.parent().unwrap_or(Path::new("."));
        let mut textures = BTreeMap::new();
        for (name, file) in &f.textures {
            let t = load_texture(&dir.join(file), &self.path)?;
            textures.insert(name.clone(), ctx.create_texture(t));
        }
        let mut materials: BTreeMap<&str, MaterialId> = BTreeMap::new();
        for (name, m) in &f.materials {
            let texture_of = |t: &Option<String>| -> Result<Option<openrt_core::TextureId>, SceneError> {
                match t {
                    None => Ok(None),
                    Some(t) => Ok(Some(*textures.get(t).ok_or_else(|| SceneError::Undefined {
                        path: self.path.clone(),
                        what: "texture",
                        name: t.clone(),
                        by: format!("material '{name}'"),
                    })?)),
                }
            };
            let (texture, emission_texture) = (texture_of(&m.texture)?, texture_of(&m.emission_texture)?);
            let id = ctx
                .create_material(Material {
                    ambient: v3(m.ambient),
                    diffuse: v3(m.diffuse),
                    specular: v3(m.specular),
                    shininess: m.shininess,
                    emission: v3(m.emission),
                    transmission: m.transmission,
                    ior: m.ior,
                    texture,
                    emission_texture,
                    one_sided: m.one_sided,
                })
                .map_err(self.core())?;
            materials.insert(name, id);
        }
        let material = |name: &Option<String>, object: &str| -> Result<MaterialId, SceneError> {
            match name {
                None => Ok(MaterialId::DEFAULT),
                Some(n) => materials.get(n.as_str()).copied().ok_or_else(|| SceneError::Undefined {
                    path: self.path.clone(),
                    what: "material",
                    name: n.clone(),
                    by: format!("object '{object}'"),
                }),
            }
        };
        let mut objects = BTreeMap::new();
        let mut morphs = Vec::new();
        let mut gltfs = Vec::new();
        let mut warnings = Vec::new();
        let start = f.animation.map_or(0.0, |a| a.start);
        for (name, o) in &f.objects {
            let id = ctx.gen_object();
            if let ObjectDesc::Morph {
                triangles,
                keys,
                material: m,
            } = o
            {
                let morph = self.morph(id, name, triangles, keys, material(m, name)?)?;
                morph.define(&mut ctx, start).map_err(self.core())?;
                morphs.push(morph);
            } else if let ObjectDesc::Gltf {
                path,
                material: m,
                scene,
                animation,
            } = o
            {
                let mut g = GltfObject {
                    id,
                    material: material(m, name)?,
                    player: Box::new(load_gltf(&self.path, path, *scene, animation.as_deref(), None)?),
                    triangles: 0,
                };
                g.define(&mut ctx, start)?;
                warnings.extend_from_slice(g.player.warnings());
                // A file with nothing to play is defined once (a static object).
                if g.player.frames() > 1 {
                    gltfs.push(g);
                }
            } else {
                ctx.begin_object(id).map_err(self.core())?;
                if let Err(e) = self.emit(&mut ctx, name, o, &material) {
                    let _ = ctx.abort_object();
                    return Err(e);
                }
                ctx.end_object().map_err(self.core())?;
            }
            objects.insert(name.as_str(), id);
        }
        let mut tracked = Vec::new();
        for (k, inst) in f.instances.iter().enumerate() {
            let id = *objects.get(inst.object.as_str()).ok_or_else(|| SceneError::Undefined {
                path: self.path.clone(),
                what: "object",
                name: inst.object.clone(),
                by: format!("instance {k}"),
            })?;
            ctx.load_identity();
            for op in &inst.transform {
                match op {
                    TransformOp::Translate(t) => ctx.translate(v3(*t)),
                    TransformOp::Rotate(axis, deg) => ctx.rotate(*deg, v3(*axis)),
                    TransformOp::Scale(s) => ctx.scale(v3(*s)),
                    TransformOp::Matrix(m) => ctx.mult_matrix(Mat4::from_cols_array(m)),
                }
                .map_err(self.core())?;
            }
            let base = ctx.current_matrix();
            let inst = ctx.instantiate(id).map_err(self.core())?;
            if let Some(keys) = &inst_keys(inst_desc_keys(f, k)) {
                tracked.push((inst, base, track(keys)));
            }
        }
        ctx.load_identity();
        let mut sway = Vec::new();
        for g in &f.generators {
            self.generate(&mut ctx, g, &mut sway)?;
        }
        let c = &f.camera;
        let camera = Camera {
            from: v3(c.from),
            at: v3(c.at),
            up: v3(c.up),
            fov_y_deg: c.fov,
            near: c.near,
        };
        camera
            .rays(f.resolution.0, f.resolution.1)
            .map_err(|e| self.invalid(format!("camera: {e}")))?;
        let env = Environment {
            lights: f
                .lights
                .iter()
                .map(|l| PointLight {
                    position: v3(l.position),
                    color: v3(l.color),
                })
                .collect(),
            ambient: v3(f.ambient),
            background: v3(f.background),
        };
        if env
            .lights
            .iter()
            .any(|l| !l.position.is_finite() || !l.color.is_finite())
            || !env.ambient.is_finite()
            || !env.background.is_finite()
        {
            return Err(self.invalid("a light, the ambient or the background colour is not finite".into()));
        }
        let animation = match f.animation {
            Some(a) if a.frames == 0 || !a.start.is_finite() || !a.end.is_finite() || a.end < a.start => {
                return Err(self.invalid(format!(
                    "animation {}..{} with {} frames is empty",
                    a.start, a.end, a.frames
                )));
            }
            Some(a) => Some(AnimationRange {
                start: a.start,
                end: a.end,
                frames: a.frames,
            }),
            None => None,
        };
        let keys = f.camera_keys.clone().unwrap_or_default();
        let mut scene = LoadedScene {
            ctx,
            camera,
            env: Arc::new(env),
            settings: RenderSettings {
                width: f.resolution.0,
                height: f.resolution.1,
                ..RenderSettings::default()
            },
            animation,
            path: self.path.clone(),
            camera_from: vec_keys(&keys.from),
            camera_at: vec_keys(&keys.at),
            tracked,
            sway,
            morphs: Vec::new(),
            gltfs: Vec::new(),
            warnings,
        };
        // Morphs and glTF objects were defined at the start time already;
        // set_time redefines them per frame.
        scene.set_time(start)?;
        scene.morphs = morphs;
        scene.gltfs = gltfs;
        Ok(scene)
    }

    fn morph(
        &self,
        id: ObjectId,
        name: &str,
        triangles: &[[u32; 3]],
        keys: &[(f32, Vec<[f32; 3]>)],
        material: MaterialId,
    ) -> Result<Morph, SceneError> {
        let Some(first) = keys.first() else {
            return Err(self.invalid(format!("object '{name}': a Morph needs at least one key")));
        };
        let n = first.1.len();
        let mut prev = f32::NEG_INFINITY;
        for (k, (t, v)) in keys.iter().enumerate() {
            if v.len() != n {
                return Err(self.invalid(format!(
                    "object '{name}': key {k} has {} vertices, key 0 has {n}",
                    v.len()
                )));
            }
            if !t.is_finite() || *t < prev {
                return Err(self.invalid(format!("object '{name}': key times must be finite and not decrease")));
            }
            prev = *t;
        }
        if let Some((t, i)) = triangles
            .iter()
            .enumerate()
            .find_map(|(t, tri)| tri.iter().find(|&&i| i as usize >= n).map(|&i| (t, i)))
        {
            return Err(self.invalid(format!(
                "object '{name}': triangle {t} uses vertex {i}, but there are {n} vertices"
            )));
        }
        Ok(Morph {
            id,
            material,
            triangles: triangles.to_vec(),
            keys: keys
                .iter()
                .map(|(t, v)| (*t, v.iter().map(|p| Vec3::from_array(*p)).collect()))
                .collect(),
        })
    }

    fn generate(
        &self,
        ctx: &mut Context,
        g: &GeneratorDesc,
        sway: &mut Vec<(InstanceId, Mat4, f32, f32)>,
    ) -> Result<(), SceneError> {
        let core = self.core();
        match *g {
            GeneratorDesc::Terrain {
                size,
                grid,
                height,
                trees,
                tree_triangles,
                tree_size,
                sway_degrees,
                seed,
            } => {
                if !(size.is_finite()
                    && size > 0.0
                    && height.is_finite()
                    && tree_size.is_finite()
                    && tree_size > 0.0
                    && sway_degrees.is_finite())
                    || grid == 0
                {
                    return Err(self.invalid(format!(
                        "Terrain: size {size}, grid {grid}, tree size {tree_size}, sway {sway_degrees}: sizes must be positive and finite, the grid at least 1"
                    )));
                }
                let ground = ctx
                    .create_material(Material {
                        diffuse: Vec3::new(0.35, 0.5, 0.25),
                        ambient: Vec3::new(0.2, 0.3, 0.15),
                        ..Material::default()
                    })
                    .map_err(&core)?;
                let bark = ctx
                    .create_material(Material {
                        diffuse: Vec3::new(0.4, 0.28, 0.15),
                        ..Material::default()
                    })
                    .map_err(&core)?;
                let leaf = [
                    ctx.create_material(Material {
                        diffuse: Vec3::new(0.2, 0.55, 0.15),
                        ..Material::default()
                    })
                    .map_err(&core)?,
                    ctx.create_material(Material {
                        diffuse: Vec3::new(0.55, 0.5, 0.1),
                        ..Material::default()
                    })
                    .map_err(&core)?,
                ];
                let field = ctx.gen_object();
                emit_triangles(ctx, field, &[(ground, heightfield(grid as usize, size, height, seed))])
                    .map_err(&core)?;
                ctx.instantiate(field).map_err(&core)?;
                let kinds: Vec<ObjectId> = (0..2)
                    .map(|k| {
                        let (b, l) = tree(tree_triangles as usize, seed + 1 + k);
                        let id = ctx.gen_object();
                        emit_triangles(ctx, id, &[(bark, b), (leaf[k as usize], l)]).map(|()| id)
                    })
                    .collect::<Result<_, _>>()
                    .map_err(&core)?;
                let mut rng = rand::rngs::SmallRng::seed_from_u64(seed ^ 0x7EE5);
                for i in 0..trees {
                    let x = rng.random_range(-0.45..0.45) * size;
                    let z = rng.random_range(-0.45..0.45) * size;
                    let y = terrain_height(x, z, size, height, seed);
                    let s = tree_size * rng.random_range(0.7..1.3);
                    let base = Mat4::from_translation(Vec3::new(x, y, z))
                        * Mat4::from_rotation_y(rng.random_range(0.0..6.3))
                        * Mat4::from_scale(Vec3::splat(s));
                    ctx.load_matrix(base).map_err(&core)?;
                    let inst = ctx.instantiate(kinds[(i % 2) as usize]).map_err(&core)?;
                    if sway_degrees != 0.0 {
                        sway.push((inst, base, rng.random_range(0.0..6.3), sway_degrees));
                    }
                }
                ctx.load_identity();
                Ok(())
            }
        }
    }

    fn emit(
        &self,
        ctx: &mut Context,
        name: &str,
        o: &ObjectDesc,
        material: &MaterialLookup<'_>,
    ) -> Result<(), SceneError> {
        let core = self.core();
        match o {
            ObjectDesc::Mesh {
                vertices,
                triangles,
                normals,
                uvs,
                material: m,
            } => {
                ctx.material(material(m, name)?).map_err(&core)?;
                for (what, len) in [
                    ("normals", normals.as_ref().map(Vec::len)),
                    ("uvs", uvs.as_ref().map(Vec::len)),
                ] {
                    if let Some(len) = len
                        && len != vertices.len()
                    {
                        return Err(self.invalid(format!(
                            "object '{name}': {len} {what} for {} vertices (one per vertex)",
                            vertices.len()
                        )));
                    }
                }
                ctx.begin(PrimitiveKind::Triangles).map_err(&core)?;
                for (t, tri) in triangles.iter().enumerate() {
                    for &i in tri {
                        let iu = i as usize;
                        let Some(p) = vertices.get(iu) else {
                            return Err(self.invalid(format!(
                                "object '{name}': triangle {t} uses vertex {i}, but there are {} vertices",
                                vertices.len()
                            )));
                        };
                        if let Some(n) = normals {
                            ctx.normal(v3(n[iu])).map_err(&core)?;
                        }
                        if let Some(uv) = uvs {
                            ctx.tex_coord(Vec2::from_array(uv[iu])).map_err(&core)?;
                        }
                        ctx.vertex(v3(*p)).map_err(&core)?;
                    }
                }
                ctx.end().map_err(&core)
            }
            ObjectDesc::Morph { .. } => Err(self.invalid(format!("object '{name}': Morph is defined per frame"))),
            ObjectDesc::Gltf { .. } => {
                Err(self.invalid(format!("object '{name}': Gltf is posed by its file's player")))
            }
            ObjectDesc::Obj { path, material: m } => {
                ctx.material(material(m, name)?).map_err(&core)?;
                let file = self.path.parent().unwrap_or(Path::new(".")).join(path);
                let bytes = read_file(&file)?;
                let models = crate::obj::parse_obj(&bytes).map_err(|e| SceneError::Invalid {
                    path: file.clone(),
                    what: format!("OBJ file (used by object '{name}' in {}): {e}", self.path.display()),
                })?;
                let count = models.iter().map(|m| m.mesh.indices.len() / 3).sum::<usize>();
                if count > MAX_SCENE_TRIANGLES {
                    return Err(SceneError::Invalid {
                        path: file.clone(),
                        what: format!(
                            "{count} triangles is beyond the limit of {MAX_SCENE_TRIANGLES} (MAX_SCENE_TRIANGLES)"
                        ),
                    });
                }
                ctx.begin(PrimitiveKind::Triangles).map_err(&core)?;
                for model in &models {
                    let mesh = &model.mesh;
                    let nv = mesh.positions.len() / 3;
                    let has_n = mesh.normals.len() == mesh.positions.len();
                    let has_uv = mesh.texcoords.len() / 2 == nv;
                    for &i in &mesh.indices {
                        let i = i as usize;
                        if i >= nv {
                            return Err(SceneError::Invalid {
                                path: file.clone(),
                                what: format!("OBJ model '{}': index {i} out of range ({nv} vertices)", model.name),
                            });
                        }
                        if has_n {
                            ctx.normal(Vec3::from_slice(&mesh.normals[3 * i..3 * i + 3]))
                                .map_err(&core)?;
                        }
                        if has_uv {
                            ctx.tex_coord(Vec2::new(mesh.texcoords[2 * i], 1.0 - mesh.texcoords[2 * i + 1]))
                                .map_err(&core)?;
                        }
                        ctx.vertex(Vec3::from_slice(&mesh.positions[3 * i..3 * i + 3]))
                            .map_err(&core)?;
                    }
                }
                ctx.end().map_err(&core)
            }
            ObjectDesc::Box { min, max, material: m } => {
                ctx.material(material(m, name)?).map_err(&core)?;
                emit_box(ctx, v3(*min), v3(*max)).map_err(&core)
            }
            ObjectDesc::Sphere {
                center,
                radius,
                segments,
                material: m,
            } => {
                ctx.material(material(m, name)?).map_err(&core)?;
                if !radius.is_finite() || *radius <= 0.0 {
                    return Err(self.invalid(format!("object '{name}': sphere radius {radius} must be positive")));
                }
                emit_sphere(ctx, v3(*center), *radius, *segments).map_err(&core)
            }
            ObjectDesc::Quad {
                corners,
                uv_scale,
                material: m,
            } => {
                ctx.material(material(m, name)?).map_err(&core)?;
                if corners.len() != 4 {
                    return Err(self.invalid(format!(
                        "object '{name}': a quad needs 4 corners, got {}",
                        corners.len()
                    )));
                }
                ctx.begin(PrimitiveKind::Quads).map_err(&core)?;
                let uv = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)];
                for (c, (u, v)) in corners.iter().zip(uv) {
                    ctx.tex_coord(Vec2::new(u, v) * *uv_scale).map_err(&core)?;
                    ctx.vertex(v3(*c)).map_err(&core)?;
                }
                ctx.end().map_err(&core)
            }
        }
    }
}

/// Every instance of `scene` in world space, into the open definition of
/// `ctx`: triangles transformed, normals through each instance's normal
/// matrix (those given, not the geometric ones), texture coordinates kept.
fn emit_world_triangles(ctx: &mut Context, scene: &openrt_core::Scene) -> Result<(), openrt_core::CoreError> {
    for r in scene.instances() {
        let tris = r.geometry.tree.triangles();
        let sh = r.geometry.shading();
        let mut positions = Vec::with_capacity(tris.len() * 3);
        let mut normals = Vec::with_capacity(tris.len() * 3);
        let mut uvs = Vec::with_capacity(tris.len() * 3);
        for (i, t) in tris.iter().enumerate() {
            for (k, &p) in t.iter().enumerate() {
                positions.push(r.to_world.transform_point3(p));
                let n = if sh.has_normals[i] {
                    r.normal_matrix * sh.normals[i][k]
                } else {
                    Vec3::ZERO
                };
                normals.push(n);
                uvs.push(sh.uvs[i][k]);
            }
        }
        let indices: Vec<u32> = (0..positions.len() as u32).collect();
        let arrays = openrt_core::VertexArrays {
            positions: &positions,
            normals: Some(&normals),
            uvs: Some(&uvs),
        };
        ctx.draw_elements(PrimitiveKind::Triangles, &arrays, &indices)?;
    }
    Ok(())
}

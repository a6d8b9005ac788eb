//! Reading a glTF file into a [`GltfPlayer`]: checks, meshes as objects,
//! nodes as instances, materials, textures, lights, camera and animation.

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

use glam::{Mat4, Quat, Vec2, Vec3, Vec4};
use gltf::animation::util::ReadOutputs;
use gltf::json::accessor::{ComponentType as C, Type as T};
use gltf::json::animation::Property as P;
use gltf::json::camera::Type as CamType;
use gltf::json::extensions::scene::khr_lights_punctual::Type as LightType;
use gltf::json::validation::Checked;
use openrt_core::{Camera, Context, Environment, Material, MaterialId, ObjectId, PrimitiveKind, Texture, TextureWrap};

use super::animation::{Channel, Interpolation, Property, Trs, WeightChannel};
use super::deform::{self, Deformer, GLTF_MAX_INFLUENCES, Influences, Prim, Shape, Skin, Target};
use super::{GLTF_SUPPORTED_REQUIRED, GltfAnimation, GltfOptions, GltfPlayer, SceneLight};
use crate::limits::{MAX_FILE_BYTES, MAX_SCENE_TRIANGLES, MAX_TEXTURE_SIDE, MAX_TEXTURE_TEXELS};
use crate::{SceneError, SceneWarning};

/// An error about `path` at the JSON path `at`.
fn invalid(path: &Path, at: &str, what: impl std::fmt::Display) -> SceneError {
    SceneError::Invalid {
        path: path.to_path_buf(),
        what: if at.is_empty() {
            format!("glTF: {what}")
        } else {
            format!("glTF {at}: {what}")
        },
    }
}

/// The indices and counts that the `gltf` crate reads without checking:
/// accessor indices of primitives, morph targets and samplers, animation
/// channels' samplers and nodes, accessor and sparse counts of zero.
fn precheck(path: &Path, root: &gltf::json::Root) -> Result<(), SceneError> {
    let accessors = root.accessors.len();
    let in_range = |at: String, index: usize, len: usize, what: &str| {
        if index < len {
            Ok(())
        } else {
            Err(invalid(
                path,
                &at,
                format!("{what} index {index} is beyond the {len} {what}s"),
            ))
        }
    };
    for (i, a) in root.accessors.iter().enumerate() {
        if a.count.0 == 0 {
            return Err(invalid(path, &format!("accessors[{i}]"), "count must be at least 1"));
        }
        if a.sparse.as_ref().is_some_and(|s| s.count.0 == 0) {
            return Err(invalid(
                path,
                &format!("accessors[{i}].sparse"),
                "count must be at least 1",
            ));
        }
    }
    // The element type an accessor must have where this loader reads it.
    let of_kind = |at: String, index: usize, types: &[T], comps: &[C]| {
        in_range(at.clone(), index, accessors, "accessor")?;
        let a = &root.accessors[index];
        let ok = matches!(a.type_, Checked::Valid(t) if types.contains(&t))
            && matches!(a.component_type, Checked::Valid(c) if comps.contains(&c.0));
        if ok {
            Ok(())
        } else {
            Err(invalid(
                path,
                &at,
                format!(
                    "accessor {index} has type {:?} of {:?}; this use needs {types:?} of {comps:?}",
                    a.type_, a.component_type
                ),
            ))
        }
    };
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            let at = || format!("meshes[{m}].primitives[{p}]");
            for a in prim.attributes.values().chain(prim.indices.iter()) {
                in_range(at(), a.value(), accessors, "accessor")?;
            }
            if matches!(prim.mode, Checked::Invalid) {
                return Err(invalid(path, &at(), "the primitive mode is not one of glTF's"));
            }
            for (semantic, a) in &prim.attributes {
                match semantic {
                    Checked::Valid(gltf::json::mesh::Semantic::Positions | gltf::json::mesh::Semantic::Normals) => {
                        of_kind(at(), a.value(), &[T::Vec3], &[C::F32])?;
                    }
                    Checked::Valid(gltf::json::mesh::Semantic::TexCoords(0)) => {
                        of_kind(at(), a.value(), &[T::Vec2], &[C::F32, C::U8, C::U16])?;
                    }
                    Checked::Valid(gltf::json::mesh::Semantic::Joints(_)) => {
                        of_kind(at(), a.value(), &[T::Vec4], &[C::U8, C::U16])?;
                    }
                    Checked::Valid(gltf::json::mesh::Semantic::Weights(_)) => {
                        of_kind(at(), a.value(), &[T::Vec4], &[C::F32, C::U8, C::U16])?;
                    }
                    _ => {}
                }
            }
            if let Some(i) = prim.indices {
                of_kind(at(), i.value(), &[T::Scalar], &[C::U8, C::U16, C::U32])?;
            }
            for t in prim.targets.iter().flatten() {
                for a in [&t.positions, &t.normals, &t.tangents].into_iter().flatten() {
                    in_range(at(), a.value(), accessors, "accessor")?;
                }
                for a in [&t.positions, &t.normals].into_iter().flatten() {
                    of_kind(at(), a.value(), &[T::Vec3], &[C::F32])?;
                }
            }
        }
    }
    for (i, skin) in root.skins.iter().enumerate() {
        let at = || format!("skins[{i}]");
        if let Some(m) = skin.inverse_bind_matrices {
            of_kind(at(), m.value(), &[T::Mat4], &[C::F32])?;
        }
        for j in skin.joints.iter().chain(skin.skeleton.iter()) {
            in_range(at(), j.value(), root.nodes.len(), "node")?;
        }
    }
    for (i, node) in root.nodes.iter().enumerate() {
        if let Some(s) = node.skin {
            in_range(format!("nodes[{i}]"), s.value(), root.skins.len(), "skin")?;
        }
        if let Some(m) = node.mesh {
            in_range(format!("nodes[{i}]"), m.value(), root.meshes.len(), "mesh")?;
        }
    }
    for (i, cam) in root.cameras.iter().enumerate() {
        let ok = match cam.type_ {
            Checked::Valid(CamType::Perspective) => cam.perspective.is_some(),
            Checked::Valid(CamType::Orthographic) => cam.orthographic.is_some(),
            Checked::Invalid => false,
        };
        if !ok {
            return Err(invalid(
                path,
                &format!("cameras[{i}]"),
                "the type is not perspective or orthographic with its parameters",
            ));
        }
    }
    let lights = root
        .extensions
        .as_ref()
        .and_then(|e| e.khr_lights_punctual.as_ref())
        .map_or(&[][..], |l| &l.lights[..]);
    for (i, l) in lights.iter().enumerate() {
        let ok = match l.type_ {
            Checked::Valid(LightType::Spot) => l.spot.is_some(),
            Checked::Valid(_) => true,
            Checked::Invalid => false,
        };
        if !ok {
            return Err(invalid(
                path,
                &format!("KHR_lights_punctual.lights[{i}]"),
                "the type is not point, spot (with its cone) or directional",
            ));
        }
    }
    for (i, node) in root.nodes.iter().enumerate() {
        if let Some(l) = node.extensions.as_ref().and_then(|e| e.khr_lights_punctual.as_ref()) {
            in_range(format!("nodes[{i}]"), l.light.value(), lights.len(), "light")?;
        }
    }
    for (i, m) in root.materials.iter().enumerate() {
        if matches!(m.alpha_mode, Checked::Invalid) {
            return Err(invalid(
                path,
                &format!("materials[{i}]"),
                "alphaMode is not OPAQUE, MASK or BLEND",
            ));
        }
    }
    for (a, anim) in root.animations.iter().enumerate() {
        for (k, s) in anim.samplers.iter().enumerate() {
            let at = format!("animations[{a}].samplers[{k}]");
            of_kind(at.clone(), s.input.value(), &[T::Scalar], &[C::F32])?;
            in_range(at.clone(), s.output.value(), accessors, "accessor")?;
            if matches!(s.interpolation, Checked::Invalid) {
                return Err(invalid(
                    path,
                    &at,
                    "the interpolation is not STEP, LINEAR or CUBICSPLINE",
                ));
            }
        }
        for (c, ch) in anim.channels.iter().enumerate() {
            let at = format!("animations[{a}].channels[{c}]");
            in_range(at.clone(), ch.sampler.value(), anim.samplers.len(), "sampler")?;
            in_range(at.clone(), ch.target.node.value(), root.nodes.len(), "node")?;
            let output = anim.samplers[ch.sampler.value()].output.value();
            let sampler_at = format!("animations[{a}].samplers[{}]", ch.sampler.value());
            match ch.target.path {
                Checked::Invalid => return Err(invalid(path, &at, "the target path is not one of glTF's")),
                Checked::Valid(P::Translation | P::Scale) => of_kind(sampler_at, output, &[T::Vec3], &[C::F32])?,
                Checked::Valid(P::Rotation) => {
                    of_kind(sampler_at, output, &[T::Vec4], &[C::F32, C::I8, C::U8, C::I16, C::U16])?;
                }
                Checked::Valid(P::MorphTargetWeights) => {
                    of_kind(
                        sampler_at,
                        output,
                        &[T::Scalar],
                        &[C::F32, C::I8, C::U8, C::I16, C::U16],
                    )?;
                }
            }
        }
    }
    Ok(())
}

/// Collects warnings, each once.
struct Warnings<'a> {
    path: &'a Path,
    list: Vec<SceneWarning>,
}

impl Warnings<'_> {
    fn add(&mut self, at: &str, msg: impl std::fmt::Display) {
        let msg = format!("glTF {at}: {msg}");
        if !self.list.iter().any(|w| w.msg == msg) {
            self.list.push(SceneWarning {
                path: self.path.to_path_buf(),
                line: 0,
                col: 0,
                msg,
            });
        }
    }
}

pub(super) fn load(path: &Path, options: &GltfOptions) -> Result<GltfPlayer, SceneError> {
    let bytes = std::fs::metadata(path)
        .map_err(|source| SceneError::Io {
            path: path.to_path_buf(),
            source,
        })?
        .len();
    if bytes > MAX_FILE_BYTES {
        return Err(invalid(
            path,
            "",
            format!("the file has {bytes} bytes, over MAX_FILE_BYTES = {MAX_FILE_BYTES}"),
        ));
    }
    let bytes = std::fs::read(path).map_err(|source| SceneError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    load_slice(path, &bytes, Some(path.parent().unwrap_or(Path::new("."))), options)
}

/// Loads a glTF or GLB held in `bytes`, named `path` in messages; external
/// files resolve against `base` (refused without one).
pub(super) fn load_slice(
    path: &Path,
    bytes: &[u8],
    base: Option<&Path>,
    options: &GltfOptions,
) -> Result<GltfPlayer, SceneError> {
    // A last guard: a panic inside the `gltf` crate on input the checks above
    // do not foresee becomes an error naming the file, not an abort.
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        load_checked(path, bytes, base, options)
    }))
    .unwrap_or_else(|p| {
        let what = p
            .downcast_ref::<&str>()
            .map(ToString::to_string)
            .or_else(|| p.downcast_ref::<String>().cloned())
            .unwrap_or_default();
        Err(invalid(path, "", format!("{INTERNAL_FAILURE}: {what}")))
    })
}

/// The message of a file that made the glTF reader fail inside.
pub const INTERNAL_FAILURE: &str = "the glTF reader failed inside on this file";

fn load_checked(
    path: &Path,
    bytes: &[u8],
    base: Option<&Path>,
    options: &GltfOptions,
) -> Result<GltfPlayer, SceneError> {
    if bytes.len() as u64 > MAX_FILE_BYTES {
        return Err(invalid(
            path,
            "",
            format!("{} bytes, over MAX_FILE_BYTES = {MAX_FILE_BYTES}", bytes.len()),
        ));
    }
    // The `gltf` crate (1.4) panics on some out-of-range indices and on
    // empty accessors, inside its own validation and readers: those are
    // checked here first, on the JSON as parsed, before it validates the rest.
    let (raw, mut notes) = parse_lenient(path, bytes)?;
    precheck(path, raw.document.as_json())?;
    let blob = raw.blob;
    let mut root = raw.document.into_json();
    // Application-specific attributes (`_NAME`), which the crate's
    // validation refuses, are not read.
    for (m, mesh) in root.meshes.iter_mut().enumerate() {
        for (k, prim) in mesh.primitives.iter_mut().enumerate() {
            let before = prim.attributes.len();
            prim.attributes
                .retain(|name, _| !matches!(name, gltf::json::validation::Checked::Invalid));
            if prim.attributes.len() < before {
                notes.push((
                    format!("meshes[{m}].primitives[{k}]"),
                    "attributes of unknown names (such as application-specific `_NAME` ones) are not read".to_string(),
                ));
            }
        }
    }
    let document = gltf::Document::from_json(root).map_err(|e| invalid(path, "", e))?;
    let gltf = gltf::Gltf { document, blob };
    let doc = &gltf.document;
    for ext in doc.extensions_required() {
        if !GLTF_SUPPORTED_REQUIRED.contains(&ext) {
            return Err(invalid(
                path,
                "extensionsRequired",
                format!(
                    "the file requires the extension {ext}, which this loader does not read (it reads {GLTF_SUPPORTED_REQUIRED:?})"
                ),
            ));
        }
    }
    let buffers = gltf::import_buffers(doc, base, gltf.blob.clone()).map_err(|e| invalid(path, "buffers", e))?;
    let mut warn = Warnings { path, list: Vec::new() };
    for (at, msg) in &notes {
        warn.add(at, msg);
    }
    for ext in doc.extensions_used() {
        if !GLTF_SUPPORTED_REQUIRED.contains(&ext) {
            warn.add(
                "extensionsUsed",
                format!("the extension {ext} is not read: the scene is rendered without it"),
            );
        }
    }
    let scene = match options.scene {
        Some(k) => doc.scenes().nth(k).ok_or_else(|| {
            invalid(
                path,
                "scenes",
                format!("--scene {k}: the file has {} scenes", doc.scenes().len()),
            )
        })?,
        None => doc
            .default_scene()
            .or_else(|| doc.scenes().next())
            .ok_or_else(|| invalid(path, "scenes", "the file has no scene"))?,
    };

    // Nodes: parents, rest transforms, and the scene's nodes parents first.
    let n = doc.nodes().len();
    let mut parents = vec![None; n];
    for node in doc.nodes() {
        for c in node.children() {
            if parents[c.index()].replace(node.index()).is_some() {
                return Err(invalid(
                    path,
                    &format!("nodes[{}]", c.index()),
                    "a node has two parents",
                ));
            }
        }
    }
    let rest: Vec<Trs> = doc
        .nodes()
        .map(|node| {
            let (t, r, s) = node.transform().decomposed();
            Trs {
                translation: Vec3::from_array(t),
                rotation: Quat::from_array(r).normalize(),
                scale: Vec3::from_array(s),
            }
        })
        .collect();
    if let Some((i, _)) = rest
        .iter()
        .enumerate()
        .find(|(_, t)| !(t.translation.is_finite() && t.rotation.is_finite() && t.scale.is_finite()))
    {
        return Err(invalid(path, &format!("nodes[{i}]"), "the transform is not finite"));
    }
    let mut order = Vec::new();
    let mut seen = vec![false; n];
    let mut stack: Vec<usize> = scene.nodes().map(|r| r.index()).collect();
    stack.reverse();
    while let Some(i) = stack.pop() {
        if std::mem::replace(&mut seen[i], true) {
            return Err(invalid(path, &format!("nodes[{i}]"), "the node hierarchy has a cycle"));
        }
        order.push(i);
        let node = doc.nodes().nth(i).expect("index in range");
        stack.extend(node.children().map(|c| c.index()).collect::<Vec<_>>().into_iter().rev());
    }

    // The chosen animations' channels.
    let (channels, weight_channels) = read_animations(path, doc, &buffers, &options.animation, &mut warn)?;
    let duration = channels
        .iter()
        .map(Channel::end)
        .chain(weight_channels.iter().map(WeightChannel::end))
        .fold(0.0, f32::max);
    // Nodes that move: animated, or under an animated node, wherever they
    // sit (joints may lie outside the scene's own nodes).
    let world_order = all_nodes_parents_first(&parents);
    let mut animated = vec![false; n];
    for c in &channels {
        animated[c.node] = true;
    }
    for &i in &world_order {
        if let Some(p) = parents[i] {
            animated[i] |= animated[p];
        }
    }

    let mut ctx = Context::new();
    let materials = convert_materials(path, base, doc, &buffers, &mut ctx, &mut warn)?;
    let meshes = convert_meshes(path, doc, &buffers, &materials, &mut ctx, &mut warn)?;

    // Morph weights at rest: the node's, else its mesh's, else zeros.
    let rest_weights: Vec<Vec<f32>> = doc
        .nodes()
        .map(|node| {
            let targets = node
                .mesh()
                .and_then(|m| meshes[m.index()].as_ref())
                .map_or(0, |p| p.iter().map(|p| p.targets.len()).max().unwrap_or(0));
            let mut w: Vec<f32> = node
                .weights()
                .or_else(|| node.mesh().and_then(|m| m.weights()))
                .map(<[f32]>::to_vec)
                .unwrap_or_default();
            w.resize(targets, 0.0);
            w
        })
        .collect();
    if let Some((i, _)) = rest_weights
        .iter()
        .enumerate()
        .find(|(_, w)| w.iter().any(|x| !x.is_finite()))
    {
        return Err(invalid(path, &format!("nodes[{i}]"), "a morph weight is not finite"));
    }
    for c in &weight_channels {
        let targets = rest_weights[c.node].len();
        if c.width != targets {
            return Err(invalid(
                path,
                &format!("nodes[{}]", c.node),
                format!(
                    "an animation gives {} morph weights per key; the node's mesh has {targets} morph targets",
                    c.width
                ),
            ));
        }
    }

    let mut player = GltfPlayer {
        ctx,
        env: Arc::new(Environment::default()),
        settings: openrt_core::RenderSettings::default(),
        path: path.to_path_buf(),
        warnings: Vec::new(),
        parents,
        rest,
        order,
        world_order,
        moving: Vec::new(),
        channels,
        weight_channels,
        rest_weights,
        deformers: Vec::new(),
        duration,
        camera: None,
        framing: Camera {
            from: Vec3::new(0.0, 0.0, 5.0),
            at: Vec3::ZERO,
            up: Vec3::Y,
            fov_y_deg: 45.0,
            near: 0.01,
        },
        static_instances: 0,
        deform_times: super::DeformTimes::default(),
        animation_names: doc.animations().map(|a| a.name().unwrap_or("").to_string()).collect(),
        lights: Vec::new(),
        light_bounds: openrt_accel::Aabb::EMPTY,
        node_animated: Vec::new(),
    };
    let world = player.world(0.0);
    let weights0 = player.weights(0.0);
    let core = |source| SceneError::Core {
        path: path.to_path_buf(),
        source,
    };
    let mut lights = Vec::new();
    let mut shared: HashMap<usize, ObjectId> = HashMap::new();
    let mut cameras_seen = Vec::new();
    let mut deformed_triangles = 0usize;
    for &i in &player.order.clone() {
        let node = doc.nodes().nth(i).expect("index in range");
        let at = format!("nodes[{i}]");
        if let Some((mesh, prims)) = node
            .mesh()
            .and_then(|m| meshes[m.index()].as_ref().map(|p| (m.index(), p)))
        {
            let skin = match node.skin() {
                Some(skin) => Some(read_skin(path, &skin, &buffers, prims, &at)?),
                None => None,
            };
            let morphs = !player.rest_weights[i].is_empty();
            let weights_move = player.weight_channels.iter().any(|c| c.node == i);
            let joints_move = skin.as_ref().is_some_and(|s| s.joints.iter().any(|&j| animated[j]));
            let own = skin.is_some() || (morphs && (weights_move || player.rest_weights[i].iter().any(|&w| w != 0.0)));
            let id = if own {
                // This node's own object, deformed now and, when its joints
                // or weights are animated, every frame.
                deformed_triangles += prims.iter().map(super::deform::Prim::triangles).sum::<usize>();
                if deformed_triangles > MAX_SCENE_TRIANGLES {
                    return Err(invalid(
                        path,
                        &at,
                        format!(
                            "skinned and morphed copies make more than MAX_SCENE_TRIANGLES = {MAX_SCENE_TRIANGLES} triangles"
                        ),
                    ));
                }
                let object = player.ctx.gen_object();
                let d = Deformer {
                    node: i,
                    object,
                    prims: Arc::clone(prims),
                    skin,
                    animated: joints_move || weights_move,
                };
                let shapes = d.shapes(&world, &weights0[i]);
                deform::define(&mut player.ctx, object, &d.prims, &shapes).map_err(|(a, e)| invalid(path, &a, e))?;
                let skinned = d.skin.is_some();
                player.deformers.push(d);
                // A skinned mesh is placed by its joints alone: the node's
                // own transform is ignored (glTF 2.0, 3.7.3.3).
                player
                    .ctx
                    .load_matrix(if skinned { Mat4::IDENTITY } else { world[i] })
                    .map_err(|e| invalid(path, &at, e))?;
                player.ctx.instantiate(object).map_err(core)?
            } else {
                let object = if let Some(&o) = shared.get(&mesh) {
                    o
                } else {
                    let o = player.ctx.gen_object();
                    let shapes: Vec<Shape> = prims.iter().map(Prim::rest).collect();
                    deform::define(&mut player.ctx, o, prims, &shapes).map_err(|(a, e)| invalid(path, &a, e))?;
                    shared.insert(mesh, o);
                    o
                };
                player.ctx.load_matrix(world[i]).map_err(|e| invalid(path, &at, e))?;
                player.ctx.instantiate(object).map_err(core)?
            };
            // Affine: an animated node's instance (a skinned mesh's stays
            // put); deforming: an object redefined every frame; else static.
            let deforming = player.deformers.last().is_some_and(|d| d.node == i && d.animated);
            if animated[i] && node.skin().is_none() {
                player.moving.push((i, id));
            } else if !deforming {
                player.static_instances += 1;
            }
        } else if node.skin().is_some() {
            warn.add(&at, "a skin without a mesh is ignored");
        }
        if let Some(cam) = node.camera() {
            cameras_seen.push((cam.index(), i));
            match cam.projection() {
                gltf::camera::Projection::Perspective(p) => {
                    let wanted = options.camera.map_or(player.camera.is_none(), |c| c == cam.index());
                    if wanted && player.camera.is_none() {
                        player.camera = Some((i, p.yfov(), p.znear().max(1e-4)));
                    }
                }
                gltf::camera::Projection::Orthographic(_) => {
                    warn.add(
                        &format!("cameras[{}]", cam.index()),
                        "orthographic cameras are not supported: skipped",
                    );
                }
            }
        }
        if let Some(light) = node.light() {
            lights.extend(convert_light(&light, i, &mut warn));
        }
    }
    if let Some(c) = options.camera
        && player.camera.is_none()
    {
        return Err(invalid(
            path,
            "cameras",
            format!(
                "--camera {c}: the scene's nodes use the perspective cameras {:?} (of {} in the file)",
                cameras_seen
                    .iter()
                    .filter(|(k, _)| doc
                        .cameras()
                        .nth(*k)
                        .is_some_and(|c| matches!(c.projection(), gltf::camera::Projection::Perspective(_))))
                    .map(|(k, _)| *k)
                    .collect::<Vec<_>>(),
                doc.cameras().len()
            ),
        ));
    }
    player.ctx.load_identity();
    player
        .set_deforming_accel(Some(super::GLTF_DEFORMING_ACCEL))
        .map_err(core)?;
    player.ctx.commit().map_err(core)?;
    // A camera framing the scene's bounds, for files without one.
    let scene_now = player.ctx.scene();
    let bounds = scene_now
        .instances()
        .iter()
        .fold(openrt_accel::Aabb::EMPTY, |b, r| b.union(r.world_bounds));
    if !bounds.is_empty() {
        let (c, r) = (bounds.center(), (bounds.max - bounds.min).length().max(1e-3) * 0.5);
        player.framing = Camera {
            from: c + Vec3::new(0.0, 0.3, 1.0).normalize() * r * 2.4,
            at: c,
            up: Vec3::Y,
            fov_y_deg: 45.0,
            near: r * 1e-3,
        };
    }
    player.lights = lights;
    player.light_bounds = bounds;
    player.node_animated = animated;
    player.env = Arc::new(player.env_at(&world, 0.0));
    player.warnings = warn.list;
    Ok(player)
}

/// KHR_lights_punctual onto point lights: a point light at its node; a spot
/// light as a point light (warned); a directional light as a point light
/// far up its direction (warned). Intensity scales nothing but zero (off):
/// the Whitted lights are unitless.
fn convert_light(
    light: &gltf::khr_lights_punctual::Light<'_>,
    node: usize,
    warn: &mut Warnings<'_>,
) -> Option<SceneLight> {
    let color = Vec3::from_array(light.color());
    if light.intensity() <= 0.0 || !color.is_finite() {
        return None;
    }
    let at = format!("KHR_lights_punctual.lights[{}]", light.index());
    let point = SceneLight {
        node,
        directional: false,
        color,
    };
    match light.kind() {
        gltf::khr_lights_punctual::Kind::Point => Some(point),
        gltf::khr_lights_punctual::Kind::Spot { .. } => {
            warn.add(&at, "a spot light is lit as a point light (no cone)");
            Some(point)
        }
        gltf::khr_lights_punctual::Kind::Directional => {
            warn.add(
                &at,
                "a directional light is lit as a point light far along its direction",
            );
            Some(SceneLight {
                directional: true,
                ..point
            })
        }
    }
}

/// glTF's metallic-roughness materials onto the Whitted model: the base
/// colour (factor times texture) is the diffuse colour of the dielectric
/// share that is not transmitted; metals reflect their base colour, rougher
/// surfaces less and with broader highlights; the transmitted share
/// refracts; `doubleSided: false` makes one-sided surfaces.
fn convert_materials(
    path: &Path,
    base: Option<&Path>,
    doc: &gltf::Document,
    buffers: &[gltf::buffer::Data],
    ctx: &mut Context,
    warn: &mut Warnings<'_>,
) -> Result<Vec<MaterialId>, SceneError> {
    let mut images: HashMap<(usize, TextureWrap, TextureWrap), openrt_core::TextureId> = HashMap::new();
    let mut out = Vec::new();
    for m in doc.materials() {
        let at = format!("materials[{}]", m.index().unwrap_or(0));
        let pbr = m.pbr_metallic_roughness();
        let base_color = Vec4::from_array(pbr.base_color_factor());
        let (metal, rough) = (
            pbr.metallic_factor().clamp(0.0, 1.0),
            pbr.roughness_factor().clamp(0.0, 1.0),
        );
        if !base_color.is_finite() {
            return Err(invalid(path, &at, "baseColorFactor is not finite"));
        }
        let rgb = base_color.truncate();
        let texture = match pbr.base_color_texture() {
            None => None,
            Some(info) => {
                if info.tex_coord() != 0 {
                    warn.add(
                        &at,
                        "a base colour texture on TEXCOORD_1 or above is read through TEXCOORD_0",
                    );
                }
                read_texture(path, base, buffers, ctx, &mut images, &info.texture(), warn)?
            }
        };
        if m.alpha_mode() != gltf::material::AlphaMode::Opaque {
            warn.add(&at, "alphaMode MASK and BLEND are rendered opaque");
        }
        // KHR_materials_emissive_strength scales the factor (Blender writes
        // it for emission stronger than 1).
        let emission = Vec3::from_array(m.emissive_factor()) * m.emissive_strength().unwrap_or(1.0);
        if !emission.is_finite() || emission.min_element() < 0.0 {
            return Err(invalid(
                path,
                &at,
                "emissiveFactor times emissive_strength is not finite and non-negative",
            ));
        }
        let emission_texture = match m.emissive_texture() {
            None => None,
            Some(info) => {
                let transform =
                    |t: Option<gltf::texture::TextureTransform<'_>>| t.map(|t| (t.offset(), t.rotation(), t.scale()));
                let base_transform = pbr.base_color_texture().and_then(|b| transform(b.texture_transform()));
                if info.tex_coord() != 0 || transform(info.texture_transform()) != base_transform {
                    warn.add(
                        &at,
                        "an emissiveTexture on other texture coordinates than the base colour's (TEXCOORD_0 and its transform) is read through those",
                    );
                }
                read_texture(path, base, buffers, ctx, &mut images, &info.texture(), warn)?
            }
        };
        // KHR_materials_transmission: the transmitted share refracts with
        // KHR_materials_ior's index (1.5 when not given, as that extension says).
        let transmission = m
            .transmission()
            .map_or(0.0, |t| t.transmission_factor())
            .clamp(0.0, 1.0)
            * (1.0 - metal);
        let ior = m.ior().unwrap_or(1.5);
        if !ior.is_finite() || ior < 1.0 {
            return Err(invalid(
                path,
                &at,
                format!("KHR_materials_ior: ior {ior} must be at least 1"),
            ));
        }
        let shine = (1.0 - rough) * (1.0 - rough);
        // KHR_materials_unlit: the base colour as it is, lit by nothing and
        // reflecting nothing: an emission of the base colour (times its
        // texture), every reflectance zero.
        let material = if m.unlit() {
            Material {
                ambient: Vec3::ZERO,
                diffuse: Vec3::ZERO,
                specular: Vec3::ZERO,
                shininess: 0.0,
                emission: rgb,
                emission_texture: texture,
                texture: None,
                transmission: 0.0,
                ior: 1.0,
                one_sided: !m.double_sided(),
            }
        } else {
            Material {
                ambient: rgb,
                transmission,
                ior,
                diffuse: rgb * (1.0 - metal) * (1.0 - transmission),
                specular: Vec3::splat(0.04).lerp(rgb, metal) * shine,
                shininess: (2.0 / (rough * rough * rough * rough).max(1e-4) - 2.0).clamp(1.0, 10_000.0),
                texture,
                emission_texture,
                one_sided: !m.double_sided(),
                emission,
            }
        };
        out.push(ctx.create_material(material).map_err(|e| invalid(path, &at, e))?);
    }
    Ok(out)
}

/// A glTF image as a texture (8-bit RGB or RGBA; alpha ignored).
fn convert_image(
    path: &Path,
    base: Option<&Path>,
    image: &gltf::image::Image<'_>,
    buffers: &[gltf::buffer::Data],
    warn: &mut Warnings<'_>,
) -> Result<Option<Texture>, SceneError> {
    let at = format!("images[{}]", image.index());
    let data = gltf::image::Data::from_source(image.source(), base, buffers).map_err(|e| invalid(path, &at, e))?;
    let channels = match data.format {
        gltf::image::Format::R8G8B8 => 3,
        gltf::image::Format::R8G8B8A8 => 4,
        other => {
            warn.add(
                &at,
                format!("{other:?} images are not read: the material is untextured"),
            );
            return Ok(None);
        }
    };
    if data.width > MAX_TEXTURE_SIDE
        || data.height > MAX_TEXTURE_SIDE
        || u64::from(data.width) * u64::from(data.height) > MAX_TEXTURE_TEXELS
    {
        return Err(invalid(
            path,
            &at,
            format!(
                "{}x{} texels, over MAX_TEXTURE_SIDE = {MAX_TEXTURE_SIDE} or MAX_TEXTURE_TEXELS = {MAX_TEXTURE_TEXELS}",
                data.width, data.height
            ),
        ));
    }
    let texels = data
        .pixels
        .chunks_exact(channels)
        .map(|p| Vec3::new(f32::from(p[0]), f32::from(p[1]), f32::from(p[2])) / 255.0)
        .collect();
    Ok(Texture::new(data.width as usize, data.height as usize, texels))
}

/// A texture of the file as a context texture: its image with its
/// sampler's wrap modes, one texture per image and addressing (`images`:
/// those made so far); `None` for an image that is not read (a warning).
fn read_texture(
    path: &Path,
    base: Option<&Path>,
    buffers: &[gltf::buffer::Data],
    ctx: &mut Context,
    images: &mut HashMap<(usize, TextureWrap, TextureWrap), openrt_core::TextureId>,
    texture: &gltf::Texture<'_>,
    warn: &mut Warnings<'_>,
) -> Result<Option<openrt_core::TextureId>, SceneError> {
    let sampler = texture.sampler();
    let wrap = |w: gltf::texture::WrappingMode| match w {
        gltf::texture::WrappingMode::Repeat => TextureWrap::Repeat,
        gltf::texture::WrappingMode::ClampToEdge => TextureWrap::ClampToEdge,
        gltf::texture::WrappingMode::MirroredRepeat => TextureWrap::MirroredRepeat,
    };
    let (u, v) = (wrap(sampler.wrap_s()), wrap(sampler.wrap_t()));
    let image = texture.source();
    if let Some(&t) = images.get(&(image.index(), u, v)) {
        return Ok(Some(t));
    }
    let t = convert_image(path, base, &image, buffers, warn)?;
    let id = t.map(|t| ctx.create_texture(t.with_wrap(u, v)));
    if let Some(id) = id {
        images.insert((image.index(), u, v), id);
    }
    Ok(id)
}

/// Parses a `.gltf` or `.glb` without the `gltf` crate's validation. Valid
/// files that the crate (1.4) cannot parse are mended first, on the JSON:
/// a scene without `nodes` gets an empty list; animation channels without
/// a target node (KHR_animation_pointer) are dropped, with a note for the
/// warnings. A file that needs none of this is parsed as it is (its errors
/// keep their line and column).
fn parse_lenient(path: &Path, bytes: &[u8]) -> Result<(gltf::Gltf, Vec<(String, String)>), SceneError> {
    let direct = gltf::Gltf::from_slice_without_validation(bytes);
    let Err(first) = direct else {
        return Ok((direct.map_err(|e| invalid(path, "", e))?, Vec::new()));
    };
    if bytes.starts_with(b"glTF") {
        let Ok(glb) = gltf::binary::Glb::from_slice(bytes) else {
            return Err(invalid(path, "", first));
        };
        let json = glb.json.into_owned();
        return mend(path, &json, glb.bin.map(std::borrow::Cow::into_owned), first);
    }
    mend(path, bytes, None, first)
}

/// [`parse_lenient`]'s mending of the JSON `json`; `first` is the error of
/// the unmended parse, reported when mending changes nothing.
fn mend(
    path: &Path,
    json: &[u8],
    blob: Option<Vec<u8>>,
    first: gltf::Error,
) -> Result<(gltf::Gltf, Vec<(String, String)>), SceneError> {
    let Ok(mut v) = serde_json::from_slice::<serde_json::Value>(json) else {
        return Err(invalid(path, "", first));
    };
    let mut notes = Vec::new();
    for scene in v.get_mut("scenes").and_then(|s| s.as_array_mut()).into_iter().flatten() {
        if let Some(o) = scene.as_object_mut() {
            o.entry("nodes").or_insert_with(|| serde_json::json!([]));
        }
    }
    for (a, anim) in v
        .get_mut("animations")
        .and_then(|s| s.as_array_mut())
        .into_iter()
        .flatten()
        .enumerate()
    {
        if let Some(channels) = anim.get_mut("channels").and_then(|c| c.as_array_mut()) {
            let before = channels.len();
            channels.retain(|c| c.get("target").and_then(|t| t.get("node")).is_some());
            if channels.len() < before {
                notes.push((
                    format!("animations[{a}]"),
                    format!(
                        "{} channels without a target node (KHR_animation_pointer) are not played",
                        before - channels.len()
                    ),
                ));
            }
        }
    }
    let root: gltf::json::Root = serde_json::from_value(v).map_err(|_| invalid(path, "", &first))?;
    Ok((
        gltf::Gltf {
            document: gltf::Document::from_json_without_validation(root),
            blob,
        },
        notes,
    ))
}

/// The KHR_texture_transform of a primitive's base colour texture as a
/// matrix on its texture coordinates (`translation * rotation * scale`, as
/// the extension defines it), or `None` without one.
fn uv_transform(
    path: &Path,
    p: &gltf::Primitive<'_>,
    warn: &mut Warnings<'_>,
) -> Result<Option<glam::Affine2>, SceneError> {
    let Some(t) = p
        .material()
        .pbr_metallic_roughness()
        .base_color_texture()
        .and_then(|info| info.texture_transform())
    else {
        return Ok(None);
    };
    let at = format!("materials[{}]", p.material().index().unwrap_or(0));
    let (offset, scale, rotation) = (Vec2::from_array(t.offset()), Vec2::from_array(t.scale()), t.rotation());
    if !(offset.is_finite() && scale.is_finite() && rotation.is_finite()) {
        return Err(invalid(
            path,
            &at,
            "KHR_texture_transform has a value that is not finite",
        ));
    }
    if t.tex_coord().is_some_and(|k| k != 0) {
        warn.add(&at, "KHR_texture_transform's texCoord is not read: TEXCOORD_0 is used");
    }
    let (s, c) = rotation.sin_cos();
    let rotate = glam::Mat2::from_cols(Vec2::new(c, s), Vec2::new(-s, c));
    Ok(Some(glam::Affine2::from_mat2_translation(
        rotate * glam::Mat2::from_diagonal(scale),
        offset,
    )))
}

/// Every mesh's primitives as read (`None` for a mesh without triangles):
/// vertices, whole-triangle indices, material, skin influences (normalized
/// weights) and morph targets.
fn convert_meshes(
    path: &Path,
    doc: &gltf::Document,
    buffers: &[gltf::buffer::Data],
    materials: &[MaterialId],
    ctx: &mut Context,
    warn: &mut Warnings<'_>,
) -> Result<Vec<Option<Arc<Vec<Prim>>>>, SceneError> {
    let default_material = ctx
        .create_material(Material {
            diffuse: Vec3::splat(0.8),
            ..Material::default()
        })
        .map_err(|e| invalid(path, "materials", e))?;
    let mut out = Vec::new();
    let mut total = 0usize;
    for mesh in doc.meshes() {
        let mut prims = Vec::new();
        for p in mesh.primitives() {
            let at = format!("meshes[{}].primitives[{}]", mesh.index(), p.index());
            let kind = match p.mode() {
                gltf::mesh::Mode::Triangles => PrimitiveKind::Triangles,
                gltf::mesh::Mode::TriangleStrip => PrimitiveKind::TriangleStrip,
                gltf::mesh::Mode::TriangleFan => PrimitiveKind::TriangleFan,
                other => {
                    warn.add(&at, format!("{other:?} primitives are not drawn"));
                    continue;
                }
            };
            let reader = p.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
            let positions: Vec<Vec3> = reader
                .read_positions()
                .ok_or_else(|| invalid(path, &at, "the primitive has no POSITION"))?
                .map(Vec3::from_array)
                .collect();
            let count = positions.len();
            let normals: Option<Vec<Vec3>> = reader.read_normals().map(|n| n.map(Vec3::from_array).collect());
            let mut uvs: Option<Vec<Vec2>> = reader
                .read_tex_coords(0)
                .map(|t| t.into_f32().map(Vec2::from_array).collect());
            if let (Some(uvs), Some(m)) = (uvs.as_mut(), uv_transform(path, &p, warn)?) {
                for uv in uvs {
                    *uv = m.transform_point2(*uv);
                }
            }
            let mut indices: Vec<u32> = match reader.read_indices() {
                Some(i) => i.into_u32().collect(),
                None => (0..count as u32).collect(),
            };
            if let Some(&bad) = indices.iter().find(|&&i| i as usize >= count) {
                return Err(invalid(
                    path,
                    &at,
                    format!("index {bad} is beyond the {count} vertices"),
                ));
            }
            if normals.as_ref().is_some_and(|n| n.len() != count) || uvs.as_ref().is_some_and(|t| t.len() != count) {
                return Err(invalid(
                    path,
                    &at,
                    "NORMAL or TEXCOORD_0 has another count than POSITION",
                ));
            }
            // Whole primitives only: a strip or fan of fewer than three
            // vertices, or a list not a multiple of three, draws what it can.
            let usable = match kind {
                PrimitiveKind::Triangles => indices.len() / 3 * 3,
                _ if indices.len() >= 3 => indices.len(),
                _ => 0,
            };
            indices.truncate(usable);
            if usable == 0 {
                continue;
            }
            let influences = read_influences(path, &at, &p, &reader, count, warn)?;
            let mut targets = Vec::new();
            for (k, (dp, dn, _)) in reader.read_morph_targets().enumerate() {
                let t = Target {
                    positions: dp.map(|d| d.map(Vec3::from_array).collect()),
                    normals: dn.map(|d| d.map(Vec3::from_array).collect()),
                };
                let lens = [t.positions.as_ref(), t.normals.as_ref()];
                if lens.iter().flatten().any(|d: &&Vec<Vec3>| d.len() != count) {
                    return Err(invalid(
                        path,
                        &format!("{at}.targets[{k}]"),
                        format!("a morph target's displacements must number the {count} vertices"),
                    ));
                }
                if lens.iter().flatten().any(|d| d.iter().any(|v| !v.is_finite())) {
                    return Err(invalid(
                        path,
                        &format!("{at}.targets[{k}]"),
                        "a morph target's displacement is not finite",
                    ));
                }
                targets.push(t);
            }
            let material = p
                .material()
                .index()
                .and_then(|i| materials.get(i))
                .copied()
                .unwrap_or(default_material);
            let prim = Prim {
                at,
                kind,
                positions,
                normals,
                uvs,
                indices,
                material,
                influences,
                targets,
            };
            total += prim.triangles();
            if total > MAX_SCENE_TRIANGLES {
                return Err(invalid(
                    path,
                    &prim.at,
                    format!("the scene has more than MAX_SCENE_TRIANGLES = {MAX_SCENE_TRIANGLES} triangles"),
                ));
            }
            prims.push(prim);
        }
        out.push((!prims.is_empty()).then(|| Arc::new(prims)));
    }
    Ok(out)
}

/// A primitive's JOINTS_0/WEIGHTS_0 and JOINTS_1/WEIGHTS_1, with each
/// vertex's weights normalized (a sum off 1 by more than 1% is warned; a
/// sum of zero, a negative or non-finite weight is refused).
fn read_influences<'a, 's, F>(
    path: &Path,
    at: &str,
    p: &gltf::Primitive<'_>,
    reader: &gltf::mesh::Reader<'a, 's, F>,
    count: usize,
    warn: &mut Warnings<'_>,
) -> Result<Option<Vec<Influences>>, SceneError>
where
    F: Clone + Fn(gltf::Buffer<'a>) -> Option<&'s [u8]>,
{
    let has = |sem| p.get(&sem).is_some();
    if has(gltf::Semantic::Joints(2)) || has(gltf::Semantic::Weights(2)) {
        warn.add(
            at,
            format!("JOINTS_2 and above are ignored: at most {GLTF_MAX_INFLUENCES} joints per vertex"),
        );
    }
    let mut out: Option<Vec<Influences>> = None;
    for set in 0..2u32 {
        let (joints, weights) = (reader.read_joints(set), reader.read_weights(set));
        let (joints, weights): (Vec<[u16; 4]>, Vec<[f32; 4]>) = match (joints, weights) {
            (None, None) => continue,
            (Some(j), Some(w)) => (j.into_u16().collect(), w.into_f32().collect()),
            _ => {
                return Err(invalid(
                    path,
                    at,
                    format!("JOINTS_{set} and WEIGHTS_{set} must come together"),
                ));
            }
        };
        if joints.len() != count || weights.len() != count {
            return Err(invalid(
                path,
                at,
                format!("JOINTS_{set} and WEIGHTS_{set} must number the {count} vertices"),
            ));
        }
        let inf = out.get_or_insert_with(|| vec![Influences::default(); count]);
        let slot = 4 * set as usize;
        for (v, (j, w)) in inf.iter_mut().zip(joints.iter().zip(&weights)) {
            v.joints[slot..slot + 4].copy_from_slice(j);
            v.weights[slot..slot + 4].copy_from_slice(w);
        }
    }
    if let Some(inf) = out.as_mut() {
        let mut off = false;
        for (i, v) in inf.iter_mut().enumerate() {
            if v.weights.iter().any(|w| !w.is_finite() || *w < 0.0) {
                return Err(invalid(
                    path,
                    at,
                    format!("vertex {i} has a negative or non-finite joint weight"),
                ));
            }
            let sum: f32 = v.weights.iter().sum();
            if sum <= 0.0 {
                return Err(invalid(path, at, format!("vertex {i}'s joint weights sum to zero")));
            }
            off |= (sum - 1.0).abs() > 0.01;
            for w in &mut v.weights {
                *w /= sum;
            }
        }
        if off {
            warn.add(at, "joint weights that do not sum to 1 are normalized");
        }
    }
    Ok(out)
}

/// A skin's joints and inverse bind matrices, checked against the
/// influences of the mesh it deforms.
fn read_skin(
    path: &Path,
    skin: &gltf::Skin<'_>,
    buffers: &[gltf::buffer::Data],
    prims: &[Prim],
    node_at: &str,
) -> Result<Skin, SceneError> {
    let at = format!("skins[{}]", skin.index());
    let joints: Vec<usize> = skin.joints().map(|j| j.index()).collect();
    if joints.is_empty() {
        return Err(invalid(path, &at, "a skin needs at least one joint"));
    }
    let inverse_bind: Vec<Mat4> = match skin
        .reader(|b| buffers.get(b.index()).map(|d| &d.0[..]))
        .read_inverse_bind_matrices()
    {
        Some(m) => m.map(|m| Mat4::from_cols_array_2d(&m)).collect(),
        None => vec![Mat4::IDENTITY; joints.len()],
    };
    if inverse_bind.len() < joints.len() {
        return Err(invalid(
            path,
            &at,
            format!(
                "{} inverse bind matrices for {} joints: one per joint is needed",
                inverse_bind.len(),
                joints.len()
            ),
        ));
    }
    if inverse_bind.iter().any(|m| !m.is_finite()) {
        return Err(invalid(path, &at, "an inverse bind matrix is not finite"));
    }
    for p in prims {
        let Some(inf) = &p.influences else {
            return Err(invalid(
                path,
                &p.at,
                format!("{node_at} is skinned by {at}, but this primitive has no JOINTS_0 and WEIGHTS_0"),
            ));
        };
        let worst = inf
            .iter()
            .flat_map(|v| {
                v.joints
                    .iter()
                    .zip(&v.weights)
                    .filter(|(_, w)| **w != 0.0)
                    .map(|(j, _)| *j)
            })
            .max();
        if let Some(j) = worst.filter(|&j| usize::from(j) >= joints.len()) {
            return Err(invalid(
                path,
                &p.at,
                format!(
                    "a vertex names joint {j}; {at} (skinning {node_at}) has {} joints",
                    joints.len()
                ),
            ));
        }
    }
    Ok(Skin { joints, inverse_bind })
}

/// Every node, parents before children (nodes on a cycle are left out).
fn all_nodes_parents_first(parents: &[Option<usize>]) -> Vec<usize> {
    let mut children = vec![Vec::new(); parents.len()];
    for (i, p) in parents.iter().enumerate() {
        if let Some(p) = p {
            children[*p].push(i);
        }
    }
    let mut out = Vec::with_capacity(parents.len());
    let mut stack: Vec<usize> = (0..parents.len()).filter(|&i| parents[i].is_none()).collect();
    while let Some(i) = stack.pop() {
        out.push(i);
        stack.extend(&children[i]);
    }
    out
}

/// The chosen animations' node and morph-weight channels, checked.
fn read_animations(
    path: &Path,
    doc: &gltf::Document,
    buffers: &[gltf::buffer::Data],
    choice: &GltfAnimation,
    warn: &mut Warnings<'_>,
) -> Result<(Vec<Channel>, Vec<WeightChannel>), SceneError> {
    let all: Vec<gltf::Animation<'_>> = doc.animations().collect();
    let names = || {
        all.iter()
            .map(|a| format!("{} {:?}", a.index(), a.name().unwrap_or("")))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let chosen: Vec<&gltf::Animation<'_>> = match choice {
        GltfAnimation::None => Vec::new(),
        GltfAnimation::All => all.iter().collect(),
        GltfAnimation::First => {
            if all.len() > 1 {
                warn.add(
                    "animations",
                    format!(
                        "{} animations: the first is played (--animation NAME, INDEX or all chooses)",
                        all.len()
                    ),
                );
            }
            all.iter().take(1).collect()
        }
        GltfAnimation::Index(k) => vec![all.get(*k).ok_or_else(|| {
            invalid(
                path,
                "animations",
                format!("--animation {k}: the file has {} animations ({})", all.len(), names()),
            )
        })?],
        GltfAnimation::Name(name) => vec![all.iter().find(|a| a.name() == Some(name.as_str())).ok_or_else(|| {
            invalid(
                path,
                "animations",
                format!("--animation {name:?}: no animation has that name ({})", names()),
            )
        })?],
    };
    let (mut channels, mut weights) = (Vec::new(), Vec::new());
    for anim in chosen {
        for ch in anim.channels() {
            let at = format!("animations[{}].samplers[{}]", anim.index(), ch.sampler().index());
            let reader = ch.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
            let times: Vec<f32> = reader
                .read_inputs()
                .ok_or_else(|| invalid(path, &at, "the key times cannot be read"))?
                .collect();
            let interpolation = match ch.sampler().interpolation() {
                gltf::animation::Interpolation::Step => Interpolation::Step,
                gltf::animation::Interpolation::Linear => Interpolation::Linear,
                gltf::animation::Interpolation::CubicSpline => Interpolation::CubicSpline,
            };
            let node = ch.target().node().index();
            let (property, values): (Property, Vec<Vec4>) = match reader.read_outputs() {
                Some(ReadOutputs::Translations(v)) => (
                    Property::Translation,
                    v.map(|t| Vec3::from_array(t).extend(0.0)).collect(),
                ),
                Some(ReadOutputs::Rotations(v)) => (Property::Rotation, v.into_f32().map(Vec4::from_array).collect()),
                Some(ReadOutputs::Scales(v)) => (Property::Scale, v.map(|s| Vec3::from_array(s).extend(0.0)).collect()),
                Some(ReadOutputs::MorphTargetWeights(v)) => {
                    let values: Vec<f32> = v.into_f32().collect();
                    let per_key = times.len()
                        * if interpolation == Interpolation::CubicSpline {
                            3
                        } else {
                            1
                        };
                    let c = WeightChannel {
                        node,
                        interpolation,
                        width: values.len().checked_div(per_key).unwrap_or(0),
                        times,
                        values,
                    };
                    c.check().map_err(|e| invalid(path, &at, e))?;
                    weights.push(c);
                    continue;
                }
                None => return Err(invalid(path, &at, "the key values cannot be read")),
            };
            let c = Channel {
                node,
                property,
                interpolation,
                times,
                values,
            };
            c.check().map_err(|e| invalid(path, &at, e))?;
            channels.push(c);
        }
    }
    Ok((channels, weights))
}

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
use openrt_core::{Camera, Context, Environment, Material, MaterialId, ObjectId, PointLight, PrimitiveKind, Texture};

use super::animation::{Channel, Interpolation, Property, Trs};
use super::{GLTF_SUPPORTED_REQUIRED, GltfPlayer};
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
            }
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

pub(super) fn load(path: &Path) -> Result<GltfPlayer, SceneError> {
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
    load_slice(path, &bytes, Some(path.parent().unwrap_or(Path::new("."))))
}

/// Loads a glTF or GLB held in `bytes`, named `path` in messages; external
/// files resolve against `base` (refused without one).
pub(super) fn load_slice(path: &Path, bytes: &[u8], base: Option<&Path>) -> Result<GltfPlayer, SceneError> {
    // A last guard: a panic inside the `gltf` crate on input the checks above
    // do not foresee becomes an error naming the file, not an abort.
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| load_checked(path, bytes, base))).unwrap_or_else(|p| {
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

fn load_checked(path: &Path, bytes: &[u8], base: Option<&Path>) -> Result<GltfPlayer, SceneError> {
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
    let raw = gltf::Gltf::from_slice_without_validation(bytes).map_err(|e| invalid(path, "", e))?;
    precheck(path, raw.document.as_json())?;
    let blob = raw.blob;
    let document = gltf::Document::from_json(raw.document.into_json()).map_err(|e| invalid(path, "", e))?;
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
    let scene = doc
        .default_scene()
        .or_else(|| doc.scenes().next())
        .ok_or_else(|| invalid(path, "scenes", "the file has no scene"))?;

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

    // The first animation's node channels.
    let mut channels = Vec::new();
    if let Some(anim) = doc.animations().next() {
        if doc.animations().len() > 1 {
            warn.add(
                "animations",
                format!("{} animations: the first is played", doc.animations().len()),
            );
        }
        for (ci, ch) in anim.channels().enumerate() {
            let at = format!("animations[{}].samplers[{}]", anim.index(), ch.sampler().index());
            let reader = ch.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
            let times: Vec<f32> = reader
                .read_inputs()
                .ok_or_else(|| invalid(path, &at, "the key times cannot be read"))?
                .collect();
            let (property, values): (Property, Vec<Vec4>) = match reader.read_outputs() {
                Some(ReadOutputs::Translations(v)) => (
                    Property::Translation,
                    v.map(|t| Vec3::from_array(t).extend(0.0)).collect(),
                ),
                Some(ReadOutputs::Rotations(v)) => (Property::Rotation, v.into_f32().map(Vec4::from_array).collect()),
                Some(ReadOutputs::Scales(v)) => (Property::Scale, v.map(|s| Vec3::from_array(s).extend(0.0)).collect()),
                Some(ReadOutputs::MorphTargetWeights(_)) => {
                    warn.add(
                        &format!("animations[{}].channels[{ci}]", anim.index()),
                        "morph target weights are not played yet: the meshes keep their base shape",
                    );
                    continue;
                }
                None => return Err(invalid(path, &at, "the key values cannot be read")),
            };
            let interpolation = match ch.sampler().interpolation() {
                gltf::animation::Interpolation::Step => Interpolation::Step,
                gltf::animation::Interpolation::Linear => Interpolation::Linear,
                gltf::animation::Interpolation::CubicSpline => Interpolation::CubicSpline,
            };
            let c = Channel {
                node: ch.target().node().index(),
                property,
                interpolation,
                times,
                values,
            };
            c.check().map_err(|e| invalid(path, &at, e))?;
            channels.push(c);
        }
    }
    let duration = channels.iter().map(Channel::end).fold(0.0, f32::max);
    let mut animated = vec![false; n];
    for c in &channels {
        animated[c.node] = true;
    }
    for &i in &order {
        if let Some(p) = parents[i] {
            animated[i] |= animated[p];
        }
    }

    let mut ctx = Context::new();
    let materials = convert_materials(path, base, doc, &buffers, &mut ctx, &mut warn)?;
    let objects = convert_meshes(path, doc, &buffers, &materials, &mut ctx, &mut warn)?;

    let mut player = GltfPlayer {
        ctx,
        env: Arc::new(Environment::default()),
        settings: openrt_core::RenderSettings::default(),
        path: path.to_path_buf(),
        warnings: Vec::new(),
        parents,
        rest,
        order,
        moving: Vec::new(),
        channels,
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
    };
    let world = player.world(0.0);
    let core = |source| SceneError::Core {
        path: path.to_path_buf(),
        source,
    };
    let mut lights = Vec::new();
    for &i in &player.order {
        let node = doc.nodes().nth(i).expect("index in range");
        if node.skin().is_some() {
            warn.add(
                &format!("nodes[{i}]"),
                "skins are not played yet: the mesh is rendered in its bind pose",
            );
        }
        if let Some(&obj) = node.mesh().and_then(|mesh| objects.get(&mesh.index())) {
            {
                player
                    .ctx
                    .load_matrix(world[i])
                    .map_err(|e| invalid(path, &format!("nodes[{i}]"), e))?;
                let id = player.ctx.instantiate(obj).map_err(core)?;
                if animated[i] {
                    player.moving.push((i, id));
                } else {
                    player.static_instances += 1;
                }
            }
        }
        if let Some(cam) = node.camera() {
            match cam.projection() {
                gltf::camera::Projection::Perspective(p) if player.camera.is_none() => {
                    player.camera = Some((i, p.yfov(), p.znear().max(1e-4)));
                }
                gltf::camera::Projection::Perspective(_) => {}
                gltf::camera::Projection::Orthographic(_) => {
                    warn.add(
                        &format!("cameras[{}]", cam.index()),
                        "orthographic cameras are not supported: skipped",
                    );
                }
            }
        }
        if let Some(light) = node.light() {
            lights.push(convert_light(&light, world[i], &mut warn));
        }
    }
    player.ctx.load_identity();
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
    let eye = player.camera(0.0).from;
    let lights = if lights.iter().flatten().count() == 0 {
        vec![PointLight {
            position: eye,
            color: Vec3::ONE,
        }]
    } else {
        lights
            .into_iter()
            .flatten()
            .map(|(p, c)| PointLight {
                position: p(&bounds),
                color: c,
            })
            .collect()
    };
    player.env = Arc::new(Environment {
        lights,
        ambient: Vec3::splat(0.1),
        background: Vec3::splat(0.2),
    });
    player.warnings = warn.list;
    Ok(player)
}

/// A light's position (given the scene's bounds, for directional lights) and colour.
type LightAt = (Box<dyn Fn(&openrt_accel::Aabb) -> Vec3>, Vec3);

/// KHR_lights_punctual onto point lights: a point light at its node; a spot
/// light as a point light (warned); a directional light as a point light
/// far up its direction (warned). Intensity scales nothing but zero (off):
/// the Whitted lights are unitless.
fn convert_light(
    light: &gltf::khr_lights_punctual::Light<'_>,
    world: Mat4,
    warn: &mut Warnings<'_>,
) -> Option<LightAt> {
    let color = Vec3::from_array(light.color());
    if light.intensity() <= 0.0 || !color.is_finite() {
        return None;
    }
    let at = format!("KHR_lights_punctual.lights[{}]", light.index());
    let pos = world.transform_point3(Vec3::ZERO);
    match light.kind() {
        gltf::khr_lights_punctual::Kind::Point => Some((Box::new(move |_| pos), color)),
        gltf::khr_lights_punctual::Kind::Spot { .. } => {
            warn.add(&at, "a spot light is lit as a point light (no cone)");
            Some((Box::new(move |_| pos), color))
        }
        gltf::khr_lights_punctual::Kind::Directional => {
            warn.add(
                &at,
                "a directional light is lit as a point light far along its direction",
            );
            let dir = world.transform_vector3(-Vec3::Z).normalize_or(-Vec3::Y);
            Some((
                Box::new(move |b: &openrt_accel::Aabb| {
                    let r = if b.is_empty() { 100.0 } else { (b.max - b.min).length() };
                    let c = if b.is_empty() { Vec3::ZERO } else { b.center() };
                    c - dir * 100.0 * r
                }),
                color,
            ))
        }
    }
}

/// glTF's metallic-roughness materials onto the Whitted model: the base
/// colour (factor times texture) is the diffuse colour of the dielectric
/// share; metals reflect their base colour, rougher surfaces less and with
/// broader highlights; `doubleSided: false` makes one-sided surfaces.
fn convert_materials(
    path: &Path,
    base: Option<&Path>,
    doc: &gltf::Document,
    buffers: &[gltf::buffer::Data],
    ctx: &mut Context,
    warn: &mut Warnings<'_>,
) -> Result<Vec<MaterialId>, SceneError> {
    let mut images: HashMap<usize, openrt_core::TextureId> = HashMap::new();
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
                let image = info.texture().source();
                if let Some(&t) = images.get(&image.index()) {
                    Some(t)
                } else {
                    let t = convert_image(path, base, &image, buffers, warn)?;
                    let id = t.map(|t| ctx.create_texture(t));
                    if let Some(id) = id {
                        images.insert(image.index(), id);
                    }
                    id
                }
            }
        };
        if m.alpha_mode() != gltf::material::AlphaMode::Opaque {
            warn.add(&at, "alphaMode MASK and BLEND are rendered opaque");
        }
        let shine = (1.0 - rough) * (1.0 - rough);
        let material = Material {
            ambient: rgb,
            diffuse: rgb * (1.0 - metal),
            specular: Vec3::splat(0.04).lerp(rgb, metal) * shine,
            shininess: (2.0 / (rough * rough * rough * rough).max(1e-4) - 2.0).clamp(1.0, 10_000.0),
            texture,
            one_sided: !m.double_sided(),
            ..Material::default()
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

/// Every mesh as one object (its primitives' triangles, each with its
/// material); meshes without triangles make no object.
fn convert_meshes(
    path: &Path,
    doc: &gltf::Document,
    buffers: &[gltf::buffer::Data],
    materials: &[MaterialId],
    ctx: &mut Context,
    warn: &mut Warnings<'_>,
) -> Result<HashMap<usize, ObjectId>, SceneError> {
    let default_material = ctx
        .create_material(Material {
            diffuse: Vec3::splat(0.8),
            ..Material::default()
        })
        .map_err(|e| invalid(path, "materials", e))?;
    let mut objects = HashMap::new();
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
            if p.morph_targets().len() > 0 {
                warn.add(&at, "morph targets are not played yet: the base shape is drawn");
            }
            let reader = p.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
            let positions: Vec<Vec3> = reader
                .read_positions()
                .ok_or_else(|| invalid(path, &at, "the primitive has no POSITION"))?
                .map(Vec3::from_array)
                .collect();
            let normals: Option<Vec<Vec3>> = reader.read_normals().map(|n| n.map(Vec3::from_array).collect());
            let uvs: Option<Vec<Vec2>> = reader
                .read_tex_coords(0)
                .map(|t| t.into_f32().map(Vec2::from_array).collect());
            let indices: Vec<u32> = match reader.read_indices() {
                Some(i) => i.into_u32().collect(),
                None => (0..positions.len() as u32).collect(),
            };
            if let Some(&bad) = indices.iter().find(|&&i| i as usize >= positions.len()) {
                return Err(invalid(
                    path,
                    &at,
                    format!("index {bad} is beyond the {} vertices", positions.len()),
                ));
            }
            if normals.as_ref().is_some_and(|n| n.len() != positions.len())
                || uvs.as_ref().is_some_and(|t| t.len() != positions.len())
            {
                return Err(invalid(
                    path,
                    &at,
                    "NORMAL or TEXCOORD_0 has another count than POSITION",
                ));
            }
            total += indices.len() / 3;
            if total > MAX_SCENE_TRIANGLES {
                return Err(invalid(
                    path,
                    &at,
                    format!("the scene has more than MAX_SCENE_TRIANGLES = {MAX_SCENE_TRIANGLES} triangles"),
                ));
            }
            let material = p
                .material()
                .index()
                .and_then(|i| materials.get(i))
                .copied()
                .unwrap_or(default_material);
            prims.push((at, kind, positions, normals, uvs, indices, material));
        }
        if prims.is_empty() {
            continue;
        }
        let id = ctx.gen_object();
        let mesh_at = format!("meshes[{}]", mesh.index());
        ctx.define_object(id, |ctx| -> Result<(), DefineError> {
            for (at, kind, positions, normals, uvs, indices, material) in &prims {
                let api = |e| DefineError::At(invalid(path, at, e));
                ctx.material(*material).map_err(api)?;
                // Whole primitives only: a strip or fan of fewer than three
                // vertices, or a list not a multiple of three, draws what it can.
                let usable = match kind {
                    PrimitiveKind::Triangles => indices.len() / 3 * 3,
                    _ if indices.len() >= 3 => indices.len(),
                    _ => 0,
                };
                if usable == 0 {
                    continue;
                }
                ctx.begin(*kind).map_err(api)?;
                for &i in &indices[..usable] {
                    let i = i as usize;
                    match normals {
                        Some(n) => ctx.normal(n[i]).map_err(api)?,
                        None => ctx.clear_normal().map_err(api)?,
                    }
                    if let Some(t) = uvs {
                        ctx.tex_coord(t[i]).map_err(api)?;
                    }
                    ctx.vertex(positions[i]).map_err(api)?;
                }
                ctx.end().map_err(api)?;
            }
            Ok(())
        })
        .map_err(|e| match e {
            DefineError::At(e) => e,
            DefineError::Core(e) => invalid(path, &mesh_at, e),
        })?;
        objects.insert(mesh.index(), id);
    }
    Ok(objects)
}

/// A failure while defining a mesh's object: one named by its primitive,
/// or the API's own (`end_object`), named by the mesh.
enum DefineError {
    At(SceneError),
    Core(openrt_core::CoreError),
}

impl From<openrt_core::CoreError> for DefineError {
    fn from(e: openrt_core::CoreError) -> Self {
        Self::Core(e)
    }
}

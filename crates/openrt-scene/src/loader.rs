//! Turning a RON scene into OpenRT-style API calls.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use glam::{Mat4, Vec2, Vec3};
use openrt_core::{
    Camera, Context, CoreError, Environment, Material, MaterialId, PointLight, PrimitiveKind, RenderSettings,
};

use crate::SceneError;
use crate::ron_format::{ObjectDesc, SUPPORTED_VERSIONS, SceneFile, TransformOp};
use crate::shapes::{emit_box, emit_sphere};
use crate::texture_io::load_texture;

/// A scene ready to render: the committed context plus what the file says
/// about viewing it.
pub struct LoadedScene {
    /// The context holding objects and instances (already committed once).
    pub ctx: Context,
    /// The camera.
    pub camera: Camera,
    /// Lights, ambient and background.
    pub env: Environment,
    /// Resolution from the file, default mode and depth.
    pub settings: RenderSettings,
}

/// Reads and builds a RON scene file.
pub fn load_ron(path: &Path) -> Result<LoadedScene, SceneError> {
    let text = std::fs::read_to_string(path).map_err(|source| SceneError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    load_ron_str(&text, path)
}

/// Builds a RON scene from text; `path` names it in errors and anchors relative texture paths.
pub fn load_ron_str(text: &str, path: &Path) -> Result<LoadedScene, SceneError> {
    let file: SceneFile = ron::from_str(text).map_err(|e| SceneError::Parse {
        path: path.to_path_buf(),
        line: e.span.start.line,
        col: e.span.start.col,
        msg: e.code.to_string(),
    })?;
    if file.version != 1 {
        return Err(SceneError::Version {
            path: path.to_path_buf(),
            found: file.version,
            supported: SUPPORTED_VERSIONS,
        });
    }
    Builder {
        path: path.to_path_buf(),
    }
    .build(&file)
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

    fn invalid(&self, what: String) -> SceneError {
        SceneError::Invalid {
            path: self.path.clone(),
            what,
        }
    }

    fn build(&self, f: &SceneFile) -> Result<LoadedScene, SceneError> {
        let mut ctx = Context::new();
        let dir = self.path.parent().unwrap_or(Path::new("."));
        let mut textures = BTreeMap::new();
        for (name, file) in &f.textures {
            let t = load_texture(&dir.join(file), &self.path)?;
            textures.insert(name.clone(), ctx.create_texture(t));
        }
        let mut materials: BTreeMap<&str, MaterialId> = BTreeMap::new();
        for (name, m) in &f.materials {
            let texture = match &m.texture {
                None => None,
                Some(t) => Some(*textures.get(t).ok_or_else(|| SceneError::Undefined {
                    path: self.path.clone(),
                    what: "texture",
                    name: t.clone(),
                    by: format!("material '{name}'"),
                })?),
            };
            let id = ctx
                .create_material(Material {
                    ambient: v3(m.ambient),
                    diffuse: v3(m.diffuse),
                    specular: v3(m.specular),
                    shininess: m.shininess,
                    transmission: m.transmission,
                    ior: m.ior,
                    texture,
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
        for (name, o) in &f.objects {
            let id = ctx.gen_object();
            ctx.begin_object(id).map_err(self.core())?;
            self.emit(&mut ctx, name, o, &material)?;
            ctx.end_object().map_err(self.core())?;
            objects.insert(name.as_str(), id);
        }
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
            ctx.instantiate(id).map_err(self.core())?;
        }
        ctx.load_identity();
        ctx.commit().map_err(self.core())?;
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
        Ok(LoadedScene {
            ctx,
            camera,
            env,
            settings: RenderSettings {
                width: f.resolution.0,
                height: f.resolution.1,
                ..RenderSettings::default()
            },
        })
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
                emit_sphere(ctx, v3(*center), *radius, (*segments).min(1024)).map_err(&core)
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

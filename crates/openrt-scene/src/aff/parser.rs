//! The AFF reader: commands, blocks, includes and keyframes.

use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

use glam::{Mat3, Mat4, Vec2, Vec3};
use openrt_core::{Camera, MAX_IMAGE_SIDE, Material, PointLight};

use super::keyframes::{RotKey, Tcb, Track, VecKey};
use super::model::{AffCounts, AffMaterial, AffMesh, AffScene, AnimNode, AnimatedTriangle, AnimationRange};
use super::tokens::{Token, TokenStream};
use crate::limits::{MAX_BLOCK_NESTING, MAX_FRAMES, MAX_HEADER_COUNT, MAX_SCENE_TRIANGLES};
use crate::{SceneError, SceneWarning};

/// Segments around a tessellated cone or sphere.
const SEGMENTS: usize = 16;

/// Reads an AFF file and everything it includes.
pub fn parse_aff(path: &Path) -> Result<AffScene, SceneError> {
    parse_aff_limited(path, MAX_SCENE_TRIANGLES)
}

/// [`parse_aff`] with a triangle limit of `triangle_limit` (tests use a small one).
pub(crate) fn parse_aff_limited(path: &Path, triangle_limit: usize) -> Result<AffScene, SceneError> {
    let ts = TokenStream::open(path)?;
    let dir = path.parent().map_or_else(|| PathBuf::from("."), Path::to_path_buf);
    let mut p = Parser {
        ts,
        dir,
        scene: AffScene {
            path: path.to_path_buf(),
            camera: Camera::default(),
            resolution: (640, 480),
            background: Vec3::ZERO,
            ambient: Vec3::ZERO,
            lights: Vec::new(),
            animation: None,
            materials: Vec::new(),
            textures: Vec::new(),
            static_mesh: AffMesh::default(),
            nodes: Vec::new(),
            animated: Vec::new(),
            tracks: HashMap::new(),
            counts: AffCounts::default(),
            warnings: Vec::new(),
        },
        fm: Material::default(),
        material_index: HashMap::new(),
        texture_index: HashMap::new(),
        xform: vec![Mat4::IDENTITY],
        node: None,
        names: HashSet::new(),
        nesting: 0,
        triangles: 0,
        triangle_limit,
        last_key_time: None,
    };
    p.commands(false)?;
    p.scene.counts.animated_node_names = p.names.len();
    p.scene.counts.lights = p.scene.lights.len();
    Ok(p.scene)
}

struct Parser {
    ts: TokenStream,
    dir: PathBuf,
    scene: AffScene,
    /// The global material state (`fm` is never reset by blocks or files).
    fm: Material,
    material_index: HashMap<[u32; 12], Vec<(Option<usize>, usize)>>,
    texture_index: HashMap<String, usize>,
    /// Static transforms from the current frame (world or node) down to here.
    xform: Vec<Mat4>,
    node: Option<usize>,
    names: HashSet<String>,
    /// Open `xs`/`x` blocks.
    nesting: usize,
    /// Triangles defined so far, animated ones included.
    triangles: usize,
    /// [`MAX_SCENE_TRIANGLES`] (lower in tests).
    triangle_limit: usize,
    /// Time of the last key kept in the list being read.
    last_key_time: Option<f32>,
}

impl Parser {
    fn err(tok: &Token, msg: impl Into<String>) -> SceneError {
        TokenStream::error(tok, msg)
    }

    /// Commands until the end of input (`block == false`) or a closing brace.
    fn commands(&mut self, block: bool) -> Result<(), SceneError> {
        loop {
            let Some(tok) = self.ts.next() else {
                if block {
                    return Err(self.ts.error_at_last("file ends inside a block: '}' expected"));
                }
                return Ok(());
            };
            match tok.text.as_str() {
                "}" if block => return Ok(()),
                "}" => return Err(Self::err(&tok, "'}' without a matching '{'")),
                "v" => self.view()?,
                "b" => self.scene.background = self.ts.vec3("background colour")?,
                "am" => self.scene.ambient = self.ts.vec3("ambient light")?,
                "a" => self.animation(&tok)?,
                "l" => self.light(&tok)?,
                "fm" => self.material_fm()?,
                "f" => self.material_f()?,
                "i" => self.include()?,
                "xs" => self.static_transform(&tok)?,
                "x" => self.animated_node(&tok)?,
                "k" => self.keyframes()?,
                "m" => self.mesh(&tok)?,
                "p" => self.polygon(false)?,
                "pp" => self.polygon(true)?,
                "tt" => self.textured_triangle(false)?,
                "ttp" => self.textured_triangle(true)?,
                "c" => self.cone()?,
                "s" => self.sphere()?,
                "tpa" => self.animated_triangle()?,
                "{" => return Err(Self::err(&tok, "'{' must follow 'xs' or 'x name'")),
                other => return Err(Self::err(&tok, format!("unknown command '{other}'"))),
            }
        }
    }

    fn expect_brace(&mut self, after: &str) -> Result<(), SceneError> {
        let t = self.ts.expect("'{'")?;
        if t.text == "{" {
            Ok(())
        } else {
            Err(Self::err(
                &t,
                format!("expected '{{' after {after}, found '{}'", t.text),
            ))
        }
    }

    fn view(&mut self) -> Result<(), SceneError> {
        loop {
            let Some(t) = self.ts.peek() else { return Ok(()) };
            let word = t.text.clone();
            match word.as_str() {
                "from" | "at" | "up" => {
                    self.ts.next();
                    let v = self.ts.vec3(&word)?;
                    match word.as_str() {
                        "from" => self.scene.camera.from = v,
                        "at" => self.scene.camera.at = v,
                        _ => self.scene.camera.up = v,
                    }
                }
                "angle" => {
                    let t = self.ts.expect("angle")?;
                    let a = self.ts.number("angle")?;
                    if !(a > 0.0 && a < 180.0) {
                        return Err(Self::err(&t, format!("angle {a} must be in (0, 180) degrees")));
                    }
                    self.scene.camera.fov_y_deg = a;
                }
                "hither" => {
                    self.ts.next();
                    self.scene.camera.near = self.ts.number("hither")?.max(0.0);
                }
                "resolution" => {
                    let t = self.ts.expect("resolution")?;
                    let w = self.ts.count("width", MAX_IMAGE_SIDE as usize)?;
                    let h = self.ts.count("height", MAX_IMAGE_SIDE as usize)?;
                    let (w, h) = (w as u32, h as u32);
                    openrt_core::check_image_size("resolution", w, h).map_err(|e| Self::err(&t, e.to_string()))?;
                    self.scene.resolution = (w, h);
                }
                _ => return Ok(()),
            }
        }
    }

    fn animation(&mut self, tok: &Token) -> Result<(), SceneError> {
        let start = self.ts.number("animation start")?;
        let end = self.ts.number("animation end")?;
        let frames = self.ts.count("frame count", MAX_FRAMES as usize)?;
        if frames == 0 || end < start {
            return Err(Self::err(
                tok,
                format!("animation range {start}..{end} with {frames} frames is empty"),
            ));
        }
        self.scene.animation = Some(AnimationRange {
            start,
            end,
            frames: frames as u32,
        });
        Ok(())
    }

    fn light(&mut self, tok: &Token) -> Result<(), SceneError> {
        let p = self.ts.vec3("light position")?;
        let color = if self.ts.number_follows_on_line(tok) {
            self.ts.vec3("light colour")?
        } else {
            Vec3::ONE
        };
        let m = *self.xform.last().expect("transform stack");
        self.scene.lights.push(PointLight {
            position: m.transform_point3(p),
            color,
        });
        Ok(())
    }

    fn material_fm(&mut self) -> Result<(), SceneError> {
        self.fm.ambient = self.ts.vec3("fm ambient")?;
        self.fm.diffuse = self.ts.vec3("fm diffuse")?;
        self.fm.specular = self.ts.vec3("fm specular")?;
        self.fm.shininess = self.ts.number("fm shininess")?;
        self.fm.transmission = self.ts.number("fm transmission")?;
        self.fm.ior = self.ts.number("fm index of refraction")?;
        Ok(())
    }

    /// NFF `f r g b Kd Ks shine T ior`.
    fn material_f(&mut self) -> Result<(), SceneError> {
        let c = self.ts.vec3("f colour")?;
        let kd = self.ts.number("f Kd")?;
        let ks = self.ts.number("f Ks")?;
        self.fm.ambient = c * kd * 0.1;
        self.fm.diffuse = c * kd;
        self.fm.specular = Vec3::splat(ks);
        self.fm.shininess = self.ts.number("f shine")?;
        self.fm.transmission = self.ts.number("f transmission")?;
        self.fm.ior = self.ts.number("f index of refraction")?;
        Ok(())
    }

    /// Index of the current material with an optional texture.
    fn material(&mut self, texture: Option<usize>) -> usize {
        let m = &self.fm;
        let key = [
            m.ambient.x,
            m.ambient.y,
            m.ambient.z,
            m.diffuse.x,
            m.diffuse.y,
            m.diffuse.z,
            m.specular.x,
            m.specular.y,
            m.specular.z,
            m.shininess,
            m.transmission,
            m.ior,
        ]
        .map(f32::to_bits);
        let list = self.material_index.entry(key).or_default();
        if let Some(&(_, i)) = list.iter().find(|(t, _)| *t == texture) {
            return i;
        }
        let i = self.scene.materials.len();
        self.scene.materials.push(AffMaterial {
            material: self.fm.clone(),
            texture,
        });
        list.push((texture, i));
        i
    }

    fn texture(&mut self, name: &str) -> usize {
        if let Some(&i) = self.texture_index.get(name) {
            return i;
        }
        let i = self.scene.textures.len();
        self.scene.textures.push(self.dir.join(name));
        self.texture_index.insert(name.to_string(), i);
        i
    }

    fn include(&mut self) -> Result<(), SceneError> {
        let _level = self.ts.number("include level")?;
        let f = self.ts.expect("include file name")?;
        let path = self.dir.join(&f.text);
        if !path.is_file() {
            return Err(Self::err(
                &f,
                format!("included file {} does not exist", path.display()),
            ));
        }
        self.ts.push_file(&path)
    }

    fn static_transform(&mut self, tok: &Token) -> Result<(), SceneError> {
        self.enter_block(tok)?;
        let s = self.ts.vec3("xs scale")?;
        let axis = self.ts.vec3("xs rotation axis")?;
        let angle = self.ts.number("xs rotation angle")?;
        let t = self.ts.vec3("xs translation")?;
        let r = match axis.try_normalize() {
            Some(a) => Mat4::from_axis_angle(a, angle.to_radians()),
            None => Mat4::IDENTITY,
        };
        self.expect_brace("xs")?;
        let m = *self.xform.last().expect("transform stack") * Mat4::from_translation(t) * r * Mat4::from_scale(s);
        self.xform.push(m);
        self.commands(true)?;
        self.xform.pop();
        self.nesting -= 1;
        Ok(())
    }

    fn animated_node(&mut self, tok: &Token) -> Result<(), SceneError> {
        self.enter_block(tok)?;
        let name = self.ts.expect("node name")?;
        if name.text == "{" {
            return Err(Self::err(tok, "'x' needs a name before '{'"));
        }
        self.expect_brace("x name")?;
        let index = self.scene.nodes.len();
        self.scene.nodes.push(AnimNode {
            name: name.text.clone(),
            parent: self.node,
            to_parent: *self.xform.last().expect("transform stack"),
            mesh: AffMesh::default(),
        });
        self.names.insert(name.text);
        self.scene.counts.animated_node_occurrences += 1;
        let saved = (
            std::mem::replace(&mut self.xform, vec![Mat4::IDENTITY]),
            self.node.replace(index),
        );
        self.commands(true)?;
        (self.xform, self.node) = saved;
        self.nesting -= 1;
        Ok(())
    }

    fn keyframes(&mut self) -> Result<(), SceneError> {
        let name = self.ts.expect("keyframe name")?;
        self.expect_brace("k name")?;
        let mut track = Track::default();
        loop {
            let t = self.ts.expect("'transl', 'rot', 'scale' or '}'")?;
            match t.text.as_str() {
                "}" => break,
                "transl" | "scale" => {
                    let n = self.ts.count("key count", MAX_HEADER_COUNT)?;
                    let mut keys = Vec::with_capacity(self.ts.capacity_for(n));
                    for _ in 0..n {
                        let at = self.ts.peek().cloned();
                        let time = self.ts.number("key time")?;
                        let value = self.ts.vec3("key value")?;
                        let key = VecKey {
                            time,
                            value,
                            tcb: self.tcb()?,
                        };
                        self.keep_key(&mut keys, key, key.time, at.as_ref(), &name.text);
                    }
                    if t.text == "transl" {
                        track.translation = keys;
                    } else {
                        track.scale = keys;
                    }
                }
                "rot" => {
                    let n = self.ts.count("key count", MAX_HEADER_COUNT)?;
                    let mut keys = Vec::with_capacity(self.ts.capacity_for(n));
                    for _ in 0..n {
                        let at = self.ts.peek().cloned();
                        let time = self.ts.number("key time")?;
                        let axis = self.ts.vec3("rotation axis")?;
                        let degrees = self.ts.number("rotation angle")?;
                        let key = RotKey {
                            time,
                            axis,
                            degrees,
                            tcb: self.tcb()?,
                        };
                        self.keep_key(&mut keys, key, key.time, at.as_ref(), &name.text);
                    }
                    track.rotation = keys;
                }
                other => return Err(Self::err(&t, format!("unknown keyframe section '{other}'"))),
            }
        }
        // The same file may be included twice: the later block wins (identical in BART).
        self.scene.tracks.insert(name.text, track);
        Ok(())
    }

    fn tcb(&mut self) -> Result<Tcb, SceneError> {
        Ok(Tcb {
            tension: self.ts.number("tension")?,
            continuity: self.ts.number("continuity")?,
            bias: self.ts.number("bias")?,
        })
    }

    /// Appends a key unless its time goes back before the last kept key's:
    /// such a key is dropped with a warning at its line (the BART reader
    /// uses the first key segment that holds a time, so a repeated run of
    /// keys never plays).
    fn keep_key<K>(&mut self, keys: &mut Vec<K>, key: K, time: f32, at: Option<&Token>, track: &str)
    where
        K: Copy,
    {
        let last = self.last_key_time.filter(|_| !keys.is_empty());
        match (last, at) {
            (Some(prev), Some(tok)) if time < prev => {
                self.scene.warnings.push(SceneWarning {
                    path: (*tok.file).clone(),
                    line: tok.line,
                    col: tok.col,
                    msg: format!("key of '{track}' at time {time} after {prev} dropped (key times must not decrease)"),
                });
            }
            _ => {
                self.last_key_time = Some(time);
                keys.push(key);
            }
        }
    }

    fn check_times(tok: &Token, times: impl Iterator<Item = f32>) -> Result<(), SceneError> {
        let mut prev = f32::NEG_INFINITY;
        for t in times {
            if t < prev {
                return Err(Self::err(
                    tok,
                    format!("key times must not decrease ({t} after {prev})"),
                ));
            }
            prev = t;
        }
        Ok(())
    }

    fn current_mesh(&mut self) -> &mut AffMesh {
        match self.node {
            Some(i) => &mut self.scene.nodes[i].mesh,
            None => &mut self.scene.static_mesh,
        }
    }

    /// Adds a triangle under the current transform.
    fn emit(
        &mut self,
        tri: [Vec3; 3],
        n: Option<[Vec3; 3]>,
        uv: Option<[Vec2; 3]>,
        material: usize,
    ) -> Result<(), SceneError> {
        self.count_triangle()?;
        let m = *self.xform.last().expect("transform stack");
        let nm = Mat3::from_mat4(m).inverse().transpose();
        let tri = tri.map(|v| m.transform_point3(v));
        let n = n.map(|n| n.map(|v| nm * v)).filter(|n| n.iter().all(|v| v.is_finite()));
        self.current_mesh().push(tri, n, uv, material);
        Ok(())
    }

    /// Counts one more triangle against [`MAX_SCENE_TRIANGLES`].
    fn count_triangle(&mut self) -> Result<(), SceneError> {
        self.triangles += 1;
        if self.triangles > self.triangle_limit {
            return Err(self.ts.error_at_last(format!(
                "the scene defines more than {} triangles (MAX_SCENE_TRIANGLES)",
                self.triangle_limit
            )));
        }
        Ok(())
    }

    /// Enters an `xs` or `x` block, checking [`MAX_BLOCK_NESTING`].
    fn enter_block(&mut self, tok: &Token) -> Result<(), SceneError> {
        self.nesting += 1;
        if self.nesting > MAX_BLOCK_NESTING {
            return Err(Self::err(
                tok,
                format!("blocks nest deeper than {MAX_BLOCK_NESTING} levels (MAX_BLOCK_NESTING)"),
            ));
        }
        Ok(())
    }

    fn mesh(&mut self, tok: &Token) -> Result<(), SceneError> {
        let (mut vertices, mut normals, mut uvs): (Vec<Vec3>, Option<Vec<Vec3>>, Option<Vec<Vec2>>) =
            (Vec::new(), None, None);
        let mut texture = None;
        let mut have_vertices = false;
        loop {
            let t = self
                .ts
                .expect("mesh section ('vertices', 'normals', 'texturecoords', 'triangles')")?;
            match t.text.as_str() {
                "vertices" => {
                    let n = self.ts.count("vertex count", MAX_HEADER_COUNT)?;
                    vertices = (0..n).map(|_| self.ts.vec3("vertex")).collect::<Result<_, _>>()?;
                    have_vertices = true;
                }
                "normals" => {
                    let n = self.ts.count("normal count", MAX_HEADER_COUNT)?;
                    normals = Some((0..n).map(|_| self.ts.vec3("normal")).collect::<Result<_, _>>()?);
                }
                "texturecoords" => {
                    let n = self.ts.count("texture coordinate count", MAX_HEADER_COUNT)?;
                    let file = self.ts.expect("texture file name")?;
                    texture = Some(self.texture(&file.text));
                    let mut list = Vec::with_capacity(self.ts.capacity_for(n));
                    for _ in 0..n {
                        list.push(Vec2::new(self.ts.number("u")?, self.ts.number("v")?));
                    }
                    uvs = Some(list);
                }
                "triangles" => {
                    if !have_vertices {
                        return Err(Self::err(&t, "mesh 'triangles' before 'vertices'"));
                    }
                    let n = self.ts.count("triangle count", MAX_HEADER_COUNT)?;
                    let material = self.material(texture);
                    for _ in 0..n {
                        let mut idx = |what: &str, len: usize| -> Result<[usize; 3], SceneError> {
                            let mut out = [0usize; 3];
                            for o in &mut out {
                                let tk = self.ts.expect(what)?;
                                let i: usize = tk.text.parse().map_err(|_| {
                                    Self::err(&tk, format!("expected {what} (a whole number), found '{}'", tk.text))
                                })?;
                                if i >= len {
                                    return Err(Self::err(&tk, format!("{what} {i} out of range (there are {len})")));
                                }
                                *o = i;
                            }
                            Ok(out)
                        };
                        let vi = idx("vertex index", vertices.len())?;
                        let ni = match &normals {
                            Some(ns) => Some(idx("normal index", ns.len())?),
                            None => None,
                        };
                        let ti = match &uvs {
                            Some(ts) => Some(idx("texture coordinate index", ts.len())?),
                            None => None,
                        };
                        let tri = vi.map(|i| vertices[i]);
                        let n = ni.map(|ni| ni.map(|i| normals.as_ref().expect("normals")[i]));
                        let uv = ti.map(|ti| ti.map(|i| uvs.as_ref().expect("uvs")[i]));
                        self.emit(tri, n, uv, material)?;
                    }
                    self.scene.counts.mesh_triangles += n;
                    self.scene.counts.mesh_instances += 1;
                    return Ok(());
                }
                other => {
                    return Err(Self::err(
                        &t,
                        format!("unknown mesh section '{other}' in mesh started at line {}", tok.line),
                    ));
                }
            }
        }
    }

    fn polygon(&mut self, with_normals: bool) -> Result<(), SceneError> {
        let n = self.ts.count("polygon vertex count", MAX_HEADER_COUNT)?;
        let mut vs = Vec::with_capacity(self.ts.capacity_for(n));
        let mut ns = Vec::with_capacity(self.ts.capacity_for(n));
        for _ in 0..n {
            vs.push(self.ts.vec3("polygon vertex")?);
            if with_normals {
                ns.push(self.ts.vec3("polygon normal")?);
            }
        }
        let material = self.material(None);
        for i in 1..n.saturating_sub(1) {
            let normals = with_normals.then(|| [ns[0], ns[i], ns[i + 1]]);
            self.emit([vs[0], vs[i], vs[i + 1]], normals, None, material)?;
        }
        self.scene.counts.polygons += 1;
        Ok(())
    }

    fn textured_triangle(&mut self, with_normals: bool) -> Result<(), SceneError> {
        let file = self.ts.expect("texture file name")?;
        let texture = Some(self.texture(&file.text));
        let (mut v, mut n, mut uv) = ([Vec3::ZERO; 3], [Vec3::ZERO; 3], [Vec2::ZERO; 3]);
        for k in 0..3 {
            v[k] = self.ts.vec3("vertex")?;
            if with_normals {
                n[k] = self.ts.vec3("normal")?;
            }
            uv[k] = Vec2::new(self.ts.number("u")?, self.ts.number("v")?);
        }
        let material = self.material(texture);
        self.emit(v, with_normals.then_some(n), Some(uv), material)?;
        self.scene.counts.textured_triangles += 1;
        Ok(())
    }

    fn cone(&mut self) -> Result<(), SceneError> {
        let base = self.ts.vec3("cone base")?;
        let rb = self.ts.number("cone base radius")?;
        let apex = self.ts.vec3("cone apex")?;
        let ra = self.ts.number("cone apex radius")?;
        let material = self.material(None);
        let axis = apex - base;
        let Some(dir) = axis.try_normalize() else {
            self.scene.counts.cones += 1;
            return Ok(());
        };
        let (u, w) = dir.any_orthonormal_pair();
        let h = axis.length();
        let ring = |k: usize| {
            let a = std::f32::consts::TAU * (k % SEGMENTS) as f32 / SEGMENTS as f32;
            u * a.cos() + w * a.sin()
        };
        for k in 0..SEGMENTS {
            let (r0, r1) = (ring(k), ring(k + 1));
            let n0 = (r0 * h + dir * (rb - ra)).normalize_or_zero();
            let n1 = (r1 * h + dir * (rb - ra)).normalize_or_zero();
            let (b0, b1, a0, a1) = (base + r0 * rb, base + r1 * rb, apex + r0 * ra, apex + r1 * ra);
            self.emit([b0, b1, a1], Some([n0, n1, n1]), None, material)?;
            self.emit([b0, a1, a0], Some([n0, n1, n0]), None, material)?;
        }
        self.scene.counts.cones += 1;
        Ok(())
    }

    fn sphere(&mut self) -> Result<(), SceneError> {
        let c = self.ts.vec3("sphere centre")?;
        let r = self.ts.number("sphere radius")?;
        let material = self.material(None);
        let stacks = SEGMENTS / 2;
        let p = |i: usize, j: usize| {
            let th = std::f32::consts::PI * i as f32 / stacks as f32;
            let ph = std::f32::consts::TAU * j as f32 / SEGMENTS as f32;
            Vec3::new(th.sin() * ph.cos(), th.cos(), th.sin() * ph.sin())
        };
        for i in 0..stacks {
            for j in 0..SEGMENTS {
                let q = [p(i, j), p(i, j + 1), p(i + 1, j + 1), p(i + 1, j)];
                for t in [[0, 1, 2], [0, 2, 3]] {
                    let n = t.map(|k| q[k]);
                    self.emit(n.map(|v| c + v * r), Some(n), None, material)?;
                }
            }
        }
        self.scene.counts.spheres += 1;
        Ok(())
    }

    fn animated_triangle(&mut self) -> Result<(), SceneError> {
        let head = self.ts.expect("sample count")?;
        let n: usize = head
            .text
            .parse()
            .ok()
            .filter(|&n| (1..=MAX_HEADER_COUNT).contains(&n))
            .ok_or_else(|| {
                Self::err(
                    &head,
                    format!("tpa needs a sample count of at least 1, found '{}'", head.text),
                )
            })?;
        self.count_triangle()?;
        let m = *self.xform.last().expect("transform stack");
        let nm = Mat3::from_mat4(m).inverse().transpose();
        let mut tri = AnimatedTriangle {
            times: Vec::with_capacity(self.ts.capacity_for(n)),
            vertices: Vec::with_capacity(self.ts.capacity_for(n)),
            normals: Vec::with_capacity(self.ts.capacity_for(n)),
            material: self.material(None),
        };
        for _ in 0..n {
            tri.times.push(self.ts.number("sample time")?);
            let (mut v, mut nn) = ([Vec3::ZERO; 3], [Vec3::ZERO; 3]);
            for k in 0..3 {
                v[k] = m.transform_point3(self.ts.vec3("vertex")?);
                nn[k] = nm * self.ts.vec3("normal")?;
            }
            tri.vertices.push(v);
            tri.normals.push(nn);
        }
        Self::check_times(&head, tri.times.iter().copied())?;
        self.scene.animated.push(tri);
        self.scene.counts.animated_triangles += 1;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_triangle_limit_counts_every_kind_of_triangle() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.aff");
        // 2 polygon triangles, 2 tt, 1 animated: 5 in all.
        std::fs::write(
            &path,
            "p 4 0 0 0 1 0 0 1 1 0 0 1 0\ntt w.ppm 0 0 0 0 0 1 0 0 1 0 0 1 0 1 0\ntt w.ppm 0 0 1 0 0 1 0 1 1 0 0 1 1 1 0\n\
             tpa 1 0 0 0 0 0 0 1 1 0 0 0 0 1 0 1 0 0 0 1\n",
        )
        .unwrap();
        assert_eq!(parse_aff_limited(&path, 5).unwrap().static_mesh.len(), 4);
        let e = parse_aff_limited(&path, 4).unwrap_err().to_string();
        assert!(e.contains("more than 4 triangles (MAX_SCENE_TRIANGLES)"), "{e}");
        assert!(e.contains("t.aff:4:"), "names the file and line: {e}");
    }
}

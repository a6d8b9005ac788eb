//! A generated glTF scene with all three motion classes: a floor (static),
//! a crate spinning on its node (affine) and a skinned tube that sways and
//! walks along its bones (deforming: skinned every frame). It is the shipped
//! example `scenes/walker.glb` and, at any size, the bench's deforming mesh.

use glam::{Mat4, Quat, Vec3};
use serde_json::{Value, json};

/// The most triangles [`skinned_figure_glb`] makes.
pub const MAX_FIGURE_TRIANGLES: usize = 4_000_000;

/// Vertices around the tube.
const AROUND: usize = 48;

/// Binary data with its buffer views and accessors.
#[derive(Default)]
struct Bin {
    data: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Bin {
    fn view(&mut self, bytes: &[u8]) -> usize {
        while !self.data.len().is_multiple_of(4) {
            self.data.push(0);
        }
        self.views
            .push(json!({"buffer": 0, "byteOffset": self.data.len(), "byteLength": bytes.len()}));
        self.data.extend_from_slice(bytes);
        self.views.len() - 1
    }

    fn floats(&mut self, v: &[f32], kind: &str, comps: usize) -> usize {
        let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
        let view = self.view(&bytes);
        let mut a = json!({"bufferView": view, "componentType": 5126, "count": v.len() / comps, "type": kind});
        if kind == "VEC3" {
            let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
            for p in v.chunks(3) {
                for k in 0..3 {
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                }
            }
            a["min"] = json!(lo);
            a["max"] = json!(hi);
        }
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    fn ints(&mut self, v: &[u32], kind: &str, comps: usize, component: u32) -> usize {
        let bytes: Vec<u8> = if component == 5123 {
            v.iter().flat_map(|&x| (x as u16).to_le_bytes()).collect()
        } else {
            v.iter().flat_map(|x| x.to_le_bytes()).collect()
        };
        let view = self.view(&bytes);
        self.accessors
            .push(json!({"bufferView": view, "componentType": component, "count": v.len() / comps, "type": kind}));
        self.accessors.len() - 1
    }

    /// The binary glTF container around `doc` (header, JSON chunk, BIN chunk).
    fn glb(mut self, mut doc: Value) -> Vec<u8> {
        while !self.data.len().is_multiple_of(4) {
            self.data.push(0);
        }
        doc["asset"] = json!({"version": "2.0", "generator": "openrt-scene skinned_figure_glb"});
        doc["buffers"] = json!([{"byteLength": self.data.len()}]);
        doc["bufferViews"] = json!(self.views);
        doc["accessors"] = json!(self.accessors);
        let mut text = serde_json::to_vec(&doc).unwrap_or_default();
        while !text.len().is_multiple_of(4) {
            text.push(b' ');
        }
        let mut out = Vec::with_capacity(28 + text.len() + self.data.len());
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&((28 + text.len() + self.data.len()) as u32).to_le_bytes());
        out.extend_from_slice(&(text.len() as u32).to_le_bytes());
        out.extend_from_slice(b"JSON");
        out.extend_from_slice(&text);
        out.extend_from_slice(&(self.data.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&self.data);
        out
    }
}

/// A GLB scene: a 12 x 12 floor, a crate spinning on its node, a camera and
/// a point light, and a tube of about `triangles` triangles (at least
/// 2 x 48 x 4, at most [`MAX_FIGURE_TRIANGLES`]), 2 high, skinned to `bones`
/// joints in a chain (2 to 16) that sway in a two-second loop while the
/// chain's root walks across the floor and back. Each vertex is weighted
/// between its two nearest joints. `scenes[0]` (the default) is all of it,
/// `scenes[1]` the skinned figure alone (for placing it in other scenes).
#[must_use]
pub fn skinned_figure_glb(triangles: usize, bones: usize) -> Vec<u8> {
    let bones = bones.clamp(2, 16);
    let rings = (triangles.min(MAX_FIGURE_TRIANGLES) / (2 * AROUND)).max(4) + 1;
    let (height, radius) = (2.0f32, 0.25f32);
    let mut bin = Bin::default();

    // The floor and the crate (static and affine meshes).
    let floor_pos = bin.floats(
        &[-6.0, 0.0, -6.0, 6.0, 0.0, -6.0, 6.0, 0.0, 6.0, -6.0, 0.0, 6.0],
        "VEC3",
        3,
    );
    let floor_idx = bin.ints(&[0, 2, 1, 0, 3, 2], "SCALAR", 1, 5123);
    let (cube_pos, cube_nrm, cube_idx) = {
        let (mut p, mut n, mut idx) = (Vec::new(), Vec::new(), Vec::new());
        for axis in 0..3 {
            for sign in [-1.0f32, 1.0] {
                let mut normal = Vec3::ZERO;
                normal[axis] = sign;
                let (u, v) = (
                    normal.any_orthonormal_vector(),
                    normal.cross(normal.any_orthonormal_vector()),
                );
                let base = (p.len() / 3) as u32;
                for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                    let q = (normal + u * a + v * b) * 0.3;
                    p.extend_from_slice(&q.to_array());
                    n.extend_from_slice(&normal.to_array());
                }
                idx.extend_from_slice(&[base, base + 1, base + 2, base, base + 2, base + 3]);
            }
        }
        (
            bin.floats(&p, "VEC3", 3),
            bin.floats(&n, "VEC3", 3),
            bin.ints(&idx, "SCALAR", 1, 5123),
        )
    };

    // The tube: rings along y, each weighted between its nearest joints.
    let (mut pos, mut nrm, mut joints, mut weights) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let step = height / (bones - 1) as f32;
    for r in 0..rings {
        let y = height * r as f32 / (rings - 1) as f32;
        let f = (y / step).min((bones - 1) as f32 - 1e-4);
        let (j, w) = (f.floor() as u32, f.fract());
        for a in 0..AROUND {
            let ang = std::f32::consts::TAU * a as f32 / AROUND as f32;
            let (s, c) = ang.sin_cos();
            pos.extend_from_slice(&[c * radius, y, s * radius]);
            nrm.extend_from_slice(&[c, 0.0, s]);
            joints.extend_from_slice(&[j, j + 1, 0, 0]);
            weights.extend_from_slice(&[1.0 - w, w, 0.0, 0.0]);
        }
    }
    let mut idx = Vec::with_capacity(rings * AROUND * 6);
    for r in 0..rings as u32 - 1 {
        for a in 0..AROUND as u32 {
            let (a0, a1) = (a, (a + 1) % AROUND as u32);
            let (p00, p01) = (r * AROUND as u32 + a0, r * AROUND as u32 + a1);
            let (p10, p11) = (p00 + AROUND as u32, p01 + AROUND as u32);
            idx.extend_from_slice(&[p00, p11, p01, p00, p10, p11]);
        }
    }
    let tube_pos = bin.floats(&pos, "VEC3", 3);
    let tube_nrm = bin.floats(&nrm, "VEC3", 3);
    let tube_joints = bin.ints(&joints, "VEC4", 4, 5123);
    let tube_weights = bin.floats(&weights, "VEC4", 4);
    let tube_idx = bin.ints(&idx, "SCALAR", 1, 5125);
    // Joint k sits at y = k * step in the bind pose.
    let ibm: Vec<f32> = (0..bones)
        .flat_map(|k| Mat4::from_translation(Vec3::new(0.0, -(k as f32) * step, 0.0)).to_cols_array())
        .collect();
    let ibm = bin.floats(&ibm, "MAT4", 16);

    // Animation: two seconds, keys every 1/8 s.
    let keys = 17;
    let times: Vec<f32> = (0..keys).map(|k| k as f32 / 8.0).collect();
    let input = bin.floats(&times, "SCALAR", 1);
    let phase = |k: usize| std::f32::consts::TAU * k as f32 / (keys - 1) as f32;
    let sway: Vec<f32> = (0..keys)
        .flat_map(|k| Quat::from_rotation_z(0.25 * phase(k).sin()).to_array())
        .collect();
    let sway = bin.floats(&sway, "VEC4", 4);
    let walk: Vec<f32> = (0..keys).flat_map(|k| [-2.0 * phase(k).cos(), 0.0, 0.0]).collect();
    let walk = bin.floats(&walk, "VEC3", 3);
    let spin: Vec<f32> = (0..keys)
        .flat_map(|k| Quat::from_rotation_y(phase(k) / 2.0).to_array())
        .collect();
    let spin = bin.floats(&spin, "VEC4", 4);

    // Nodes: 0 floor, 1 crate, 2 tube (skinned), 3 camera, 4 light, 5.. joints.
    let mut nodes = vec![
        json!({"name": "floor", "mesh": 0}),
        json!({"name": "crate", "mesh": 1, "translation": [2.5, 0.6, -1.5]}),
        json!({"name": "tube", "mesh": 2, "skin": 0}),
        json!({"name": "camera", "camera": 0, "translation": [0.0, 2.2, 7.5], "rotation": Quat::from_rotation_x(-0.15).to_array()}),
        json!({"name": "light", "translation": [2.0, 6.0, 4.0], "extensions": {"KHR_lights_punctual": {"light": 0}}}),
    ];
    for k in 0..bones {
        let mut j = json!({"name": format!("joint{k}"), "translation": [0.0, if k == 0 { 0.0 } else { step }, 0.0]});
        if k + 1 < bones {
            j["children"] = json!([5 + k + 1]);
        }
        nodes.push(j);
    }
    let mut channels = vec![
        json!({"sampler": 0, "target": {"node": 5, "path": "translation"}}),
        json!({"sampler": 2, "target": {"node": 1, "path": "rotation"}}),
    ];
    for k in 1..bones {
        channels.push(json!({"sampler": 1, "target": {"node": 5 + k, "path": "rotation"}}));
    }
    let doc = json!({
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": [{"type": "point", "color": [1.0, 1.0, 1.0], "intensity": 1.0}]}},
        "scene": 0,
        "scenes": [
            {"name": "walker", "nodes": [0, 1, 2, 3, 4, 5]},
            {"name": "figure", "nodes": [2, 5]}
        ],
        "nodes": nodes,
        "skins": [{"joints": (5..5 + bones).collect::<Vec<_>>(), "inverseBindMatrices": ibm, "skeleton": 5}],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.05}}],
        "materials": [
            {"name": "floor", "pbrMetallicRoughness": {"baseColorFactor": [0.55, 0.55, 0.6, 1.0], "metallicFactor": 0.3, "roughnessFactor": 0.4}},
            {"name": "crate", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.5, 0.2, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.7}},
            {"name": "tube", "pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.6, 0.3, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.3}}
        ],
        "meshes": [
            {"name": "floor", "primitives": [{"attributes": {"POSITION": floor_pos}, "indices": floor_idx, "material": 0}]},
            {"name": "crate", "primitives": [{"attributes": {"POSITION": cube_pos, "NORMAL": cube_nrm}, "indices": cube_idx, "material": 1}]},
            {"name": "tube", "primitives": [{"attributes": {"POSITION": tube_pos, "NORMAL": tube_nrm, "JOINTS_0": tube_joints, "WEIGHTS_0": tube_weights}, "indices": tube_idx, "material": 2}]}
        ],
        "animations": [{"name": "walk", "channels": channels, "samplers": [
            {"input": input, "output": walk},
            {"input": input, "output": sway},
            {"input": input, "output": spin}
        ]}]
    });
    bin.glb(doc)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_figure_has_the_triangles_asked_for_and_loads() {
        for want in [1000, 10_000] {
            let bytes = skinned_figure_glb(want, 4);
            let p = super::super::GltfPlayer::from_slice(&bytes).unwrap();
            let classes = p.motion_classes();
            assert_eq!(classes.static_instances, 1, "the floor");
            assert_eq!(classes.affine_instances, 1, "the crate");
            assert_eq!(classes.deforming_objects, 1, "the tube");
            let tube = classes.deforming_triangles;
            assert!(tube.abs_diff(want) <= 2 * AROUND, "{tube} for {want}");
            assert!(p.warnings().is_empty(), "{:?}", p.warnings());
        }
        let figure = super::super::GltfPlayer::from_slice_with(
            &skinned_figure_glb(1000, 4),
            &super::super::GltfOptions {
                scene: Some(1),
                ..super::super::GltfOptions::default()
            },
        )
        .unwrap();
        let classes = figure.motion_classes();
        assert_eq!(
            (
                classes.static_instances,
                classes.affine_instances,
                classes.deforming_objects
            ),
            (0, 0, 1),
            "scenes[1]: the figure alone"
        );
    }
}

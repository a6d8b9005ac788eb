//! Builds glTF files for the tests: binary data with its buffer views and
//! accessors, the JSON around them, written as `.gltf` + `.bin` or as `.glb`.

#![allow(dead_code)]

use std::path::{Path, PathBuf};

use serde_json::{Value, json};

/// Builds a glTF file: binary data with its buffer views and accessors, and
/// the JSON around them.
#[derive(Default)]
pub struct Builder {
    pub bin: Vec<u8>,
    pub views: Vec<Value>,
    pub accessors: Vec<Value>,
}

impl Builder {
    /// Pads the binary data to a multiple of four bytes.
    fn pad(&mut self) {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
    }

    /// An accessor of `f32` values (`kind` VEC3, VEC4, SCALAR...).
    pub fn floats(&mut self, data: &[f32], kind: &str, comps: usize) -> usize {
        self.pad();
        let offset = self.bin.len();
        for v in data {
            self.bin.extend_from_slice(&v.to_le_bytes());
        }
        self.views
            .push(json!({"buffer": 0, "byteOffset": offset, "byteLength": data.len() * 4}));
        let count = data.len() / comps;
        let mut acc = json!({"bufferView": self.views.len() - 1, "componentType": 5126, "count": count, "type": kind});
        if kind == "VEC3" {
            // POSITION accessors need their bounds.
            let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
            for p in data.chunks(3) {
                for a in 0..3 {
                    lo[a] = lo[a].min(p[a]);
                    hi[a] = hi[a].max(p[a]);
                }
            }
            acc["min"] = json!(lo);
            acc["max"] = json!(hi);
        }
        self.accessors.push(acc);
        self.accessors.len() - 1
    }

    /// An accessor of `u16` values (`kind` VEC4 for JOINTS_0...).
    pub fn shorts(&mut self, data: &[u16], kind: &str, comps: usize) -> usize {
        self.pad();
        let offset = self.bin.len();
        for v in data {
            self.bin.extend_from_slice(&v.to_le_bytes());
        }
        self.views
            .push(json!({"buffer": 0, "byteOffset": offset, "byteLength": data.len() * 2}));
        self.accessors.push(json!({"bufferView": self.views.len() - 1, "componentType": 5123, "count": data.len() / comps, "type": kind}));
        self.accessors.len() - 1
    }

    /// An accessor of `u16` indices.
    pub fn indices(&mut self, data: &[u16]) -> usize {
        self.shorts(data, "SCALAR", 1)
    }

    /// The document: `doc` gets the buffers, views and accessors.
    pub fn finish(&mut self, mut doc: Value, uri: Option<&str>) -> Value {
        self.pad();
        doc["asset"] = json!({"version": "2.0"});
        let mut buffer = json!({"byteLength": self.bin.len()});
        if let Some(u) = uri {
            buffer["uri"] = json!(u);
        }
        doc["buffers"] = json!([buffer]);
        doc["bufferViews"] = json!(self.views);
        doc["accessors"] = json!(self.accessors);
        doc
    }

    /// Writes `NAME.gltf` and its `NAME.bin`.
    pub fn write_gltf(&mut self, dir: &Path, name: &str, doc: Value) -> PathBuf {
        let bin = format!("{name}.bin");
        let doc = self.finish(doc, Some(&bin));
        std::fs::write(dir.join(&bin), &self.bin).unwrap();
        let path = dir.join(format!("{name}.gltf"));
        std::fs::write(&path, serde_json::to_vec_pretty(&doc).unwrap()).unwrap();
        path
    }

    /// Writes `NAME.glb`: the binary container (header, JSON chunk, BIN chunk).
    pub fn write_glb(&mut self, dir: &Path, name: &str, doc: Value) -> PathBuf {
        let doc = self.finish(doc, None);
        let mut json = serde_json::to_vec(&doc).unwrap();
        while !json.len().is_multiple_of(4) {
            json.push(b' ');
        }
        let total = 12 + 8 + json.len() + 8 + self.bin.len();
        let mut out = Vec::new();
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&(json.len() as u32).to_le_bytes());
        out.extend_from_slice(b"JSON");
        out.extend_from_slice(&json);
        out.extend_from_slice(&(self.bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&self.bin);
        let path = dir.join(format!("{name}.glb"));
        std::fs::write(&path, out).unwrap();
        path
    }
}

//! The glTF loader on arbitrary bytes, as a `.gltf` (JSON) and as a `.glb`
//! (binary container) beside the same bytes: every input loads or is a typed
//! error, never a panic, an abort or a hang.

#![no_main]

#[path = "common.rs"]
mod common;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(p) = openrt_scene::GltfPlayer::from_slice(data) {
        common::exercise(openrt_scene::ScenePlayer::Gltf(Box::new(p)));
    }
    for name in ["main.gltf", "main.glb"] {
        let path = common::write(name, data);
        if let Ok(p) = openrt_scene::ScenePlayer::open(Some(&path)) {
            common::exercise(p);
        }
    }
});

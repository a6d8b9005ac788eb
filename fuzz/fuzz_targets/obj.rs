//! OBJ files: tobj's parser, then the project's conversion into an object
//! (through a RON scene that instances the file).

#![no_main]

#[path = "common.rs"]
mod common;

use libfuzzer_sys::fuzz_target;

const SCENE: &str = "(version: 2, camera: (from: (0.0, 1.0, 6.0), at: (0.0, 0.3, 0.0)), \
    lights: [(position: (3.0, 5.0, 4.0))], objects: { \"o\": Obj(path: \"fuzz.obj\") }, \
    instances: [(object: \"o\")])";

fuzz_target!(|data: &[u8]| {
    let _ = openrt_scene::parse_obj(data);
    common::write("fuzz.obj", data);
    let scene = common::write("obj.ron", SCENE.as_bytes());
    if let Ok(p) = openrt_scene::ScenePlayer::open(Some(&scene)) {
        common::exercise(p);
    }
});

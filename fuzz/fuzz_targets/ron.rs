//! The RON scene loader (version 1 and 2 files; the BART wrapper needs the
//! BART folder and is left to the AFF target).

#![no_main]

#[path = "common.rs"]
mod common;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let path = common::write("main.ron", data);
    if let Ok(p) = openrt_scene::ScenePlayer::open(Some(&path)) {
        common::exercise(p);
    }
});

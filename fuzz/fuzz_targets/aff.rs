//! The AFF reader, with an include file: the input is the main file, then
//! optionally a 0xFF byte and the file `inc.aff` that it may include.

#![no_main]

#[path = "common.rs"]
mod common;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let (main, inc) = match data.iter().position(|&b| b == 0xFF) {
        Some(i) => (&data[..i], &data[i + 1..]),
        None => (data, &b""[..]),
    };
    common::write("inc.aff", inc);
    let path = common::write("main.aff", main);
    if let Ok(p) = openrt_scene::ScenePlayer::open(Some(&path)) {
        common::exercise(p);
    }
});

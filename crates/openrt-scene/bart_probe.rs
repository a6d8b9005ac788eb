// The BART-data probe shared by the build scripts of openrt-scene and the
// viewer (`include!`d by both).

use std::path::{Path, PathBuf};

fn main() {
    println!("cargo::rustc-check-cfg=cfg(bart_data)");
    println!("cargo::rerun-if-env-changed=OPENRT_BART_DIR");
    let dir = std::env::var_os("OPENRT_BART_DIR").map_or_else(
        || Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/bart"),
        PathBuf::from,
    );
    let probe = dir.join("kitchen/kitchen.aff");
    println!("cargo::rerun-if-changed={}", probe.display());
    if probe.is_file() {
        println!("cargo::rustc-cfg=bart_data");
    }
}

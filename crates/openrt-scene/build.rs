//! Tells the tests whether the BART data is here: `cfg(bart_data)` is set
//! when `OPENRT_BART_DIR` (or `../shared/bart` beside the repository) holds
//! the kitchen. Tests that need the data are then `ignore`d with the reason
//! when it is missing, so the summary shows they did not run.

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

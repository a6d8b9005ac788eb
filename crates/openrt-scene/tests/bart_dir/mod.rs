//! Where the tests find the BART data: `OPENRT_BART_DIR`, else
//! `../shared/bart` beside the repository.

use std::path::{Path, PathBuf};

/// The BART folder, or `None` (with the reason printed) when it is not
/// there; a missing folder fails the test when `CI` is set.
pub fn bart() -> Option<PathBuf> {
    let dir = std::env::var_os("OPENRT_BART_DIR").map_or_else(
        || Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/bart"),
        PathBuf::from,
    );
    if dir.join("kitchen/kitchen.aff").is_file() {
        return Some(dir);
    }
    assert!(
        std::env::var_os("CI").is_none(),
        "BART data missing at {} (set OPENRT_BART_DIR)",
        dir.display()
    );
    println!(
        "skipped: BART data not found at {} (set OPENRT_BART_DIR)",
        dir.display()
    );
    None
}

//! The same probe as openrt-scene's build script: `cfg(bart_data)` when
//! the BART data is found (see `crates/openrt-scene/bart_probe.rs`).

include!("../../crates/openrt-scene/bart_probe.rs");

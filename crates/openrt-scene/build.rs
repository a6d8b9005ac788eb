//! Tells the tests whether the BART data is here: `cfg(bart_data)` is set
//! when `OPENRT_BART_DIR` (or `../shared/bart` beside the repository) holds
//! the kitchen. Tests that need the data are then `ignore`d with the reason
//! when it is missing, so the summary shows they did not run.

include!("bart_probe.rs");

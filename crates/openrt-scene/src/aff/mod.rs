//! BART's AFF format (Lext, Assarsson & Möller, "A Benchmark for Animated
//! Ray Tracing", IEEE CG&A 2001): reader, keyframes, and the player that
//! drives the OpenRT-style API.

mod keyframes;
mod model;
mod parser;
mod player;
mod tokens;

pub use keyframes::{RotKey, Tcb, Track, VecKey, interpolate_rot, interpolate_vec};
pub use model::{AffCounts, AffMaterial, AffMesh, AffScene, AnimNode, AnimatedTriangle, AnimationRange};
pub use parser::parse_aff;
pub use player::{AffPlayer, bart_dir, bart_dir_candidates};

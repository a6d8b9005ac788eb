//! What tests and benchmarks compare against: the brute-force f64 oracle
//! and deterministic mesh and ray generators.

pub mod meshgen;
pub mod oracle;

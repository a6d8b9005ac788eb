//! Leaves shared by kd-trees and BVHs: triangle blocks tested four at a
//! time, the tie rule of closest hits, packets tested across lanes, and
//! the mailbox of a packet's walk.

pub(crate) mod blocks;
pub(crate) mod mailbox;
#[cfg(target_arch = "x86_64")]
mod pairs_avx2;

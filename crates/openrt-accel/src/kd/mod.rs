//! Object kd-trees: the 8-byte node, the SAH builders (exact after Wald &
//! Havran 2006, binned), the fast builder and its refit for unstructured
//! motion, and the front-to-back walk shared with the top-level BSP.

pub(crate) mod binned_sah;
pub(crate) mod fast_build;
pub(crate) mod node;
pub(crate) mod refit;
pub(crate) mod sah_build;
pub(crate) mod sah_params;
pub(crate) mod traverse;
pub(crate) mod tree;

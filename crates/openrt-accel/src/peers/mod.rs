//! Peers measured beside the kernels (feature `embree`): Embree 3.

pub(crate) mod embree;

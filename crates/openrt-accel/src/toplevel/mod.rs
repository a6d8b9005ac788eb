//! The top level: the paper's BSP over instance boxes (Algorithm 1),
//! rebuilt every frame.

pub(crate) mod bsp;

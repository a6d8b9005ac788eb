//! Ray packets: the lane width chosen at run time, lanes laid out by axis,
//! frustums and interval bounds for culling whole packets, the watertight
//! test across lanes, and the kd-tree walk of a packet.

pub(crate) mod boxes;
pub(crate) mod frustum;
pub(crate) mod interval;
pub(crate) mod traverse;
pub(crate) mod triangle;
pub(crate) mod width;

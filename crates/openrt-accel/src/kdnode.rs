//! The compact 8-byte kd-tree node (after pbrt-v4's `KdTreeNode`).

/// Deepest tree any builder may produce; sizes the traversal stack.
pub const MAX_DEPTH: usize = 64;

/// Flag value of the low two bits that marks a leaf.
const LEAF: u32 = 3;

/// Largest child index or primitive count that fits in the 30 upper bits.
pub(crate) const MAX_FIELD: u32 = (1 << 30) - 1;

/// The error of a tree whose node indices or leaf references outgrow
/// [`MAX_FIELD`].
pub(crate) const fn too_many_nodes() -> crate::AccelError {
    crate::AccelError::TooManyNodes {
        limit: MAX_FIELD as usize,
    }
}

/// A kd-tree node in 8 bytes.
///
/// - interior: `a` holds the split position's bits, the low two bits of `b`
///   the split axis (0, 1, 2) and its upper 30 bits the index of the *above*
///   child; the *below* child is implicitly the next node.
/// - leaf: the low two bits of `b` are 3, its upper bits the primitive count,
///   and `a` the offset of the leaf's list in the tree's primitive index array.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C)]
pub struct KdNode {
    a: u32,
    b: u32,
}

const _: () = assert!(std::mem::size_of::<KdNode>() == 8);

/// Appends a subtree (a node array rooted at 0 with its own leaf lists) to
/// a depth-first array, shifting its child indices and list offsets: how
/// subtrees built on other threads join the tree.
pub(crate) fn append_shifted(
    nodes: &mut Vec<KdNode>,
    prims: &mut Vec<u32>,
    sub_nodes: &[KdNode],
    sub_prims: &[u32],
) -> Result<(), crate::AccelError> {
    let (at, prim_at) = (nodes.len(), prims.len());
    if at + sub_nodes.len() > MAX_FIELD as usize || prim_at + sub_prims.len() > u32::MAX as usize {
        return Err(too_many_nodes());
    }
    nodes.resize(at + sub_nodes.len(), KdNode::leaf(0, 0));
    shift_into(&mut nodes[at..], sub_nodes, at as u32, prim_at as u32)?;
    prims.extend_from_slice(sub_prims);
    Ok(())
}

/// Writes `src` into `dst` (same length) shifted as [`KdNode::shifted`]
/// does: a subtree's nodes placed at `node_offset` of a larger array whose
/// leaf lists it joins at `prim_offset`.
pub(crate) fn shift_into(
    dst: &mut [KdNode],
    src: &[KdNode],
    node_offset: u32,
    prim_offset: u32,
) -> Result<(), crate::AccelError> {
    debug_assert_eq!(dst.len(), src.len());
    for (d, s) in dst.iter_mut().zip(src) {
        *d = s.shifted(node_offset, prim_offset).ok_or(too_many_nodes())?;
    }
    Ok(())
}

/// Appends an interior node splitting `axis` at `split`, then the `left`
/// and `right` subtrees (see [`append_shifted`]).
pub(crate) fn stitch(
    nodes: &mut Vec<KdNode>,
    prims: &mut Vec<u32>,
    (axis, split): (usize, f32),
    left: (&[KdNode], &[u32]),
    right: (&[KdNode], &[u32]),
) -> Result<(), crate::AccelError> {
    let index = nodes.len();
    nodes.push(KdNode::interior(axis, split));
    append_shifted(nodes, prims, left.0, left.1)?;
    let above = nodes.len() as u32;
    nodes[index].set_above_child(above);
    append_shifted(nodes, prims, right.0, right.1)
}

impl KdNode {
    /// An interior node splitting `axis` at `split`; the above child's index is set later.
    #[must_use]
    pub(crate) fn interior(axis: usize, split: f32) -> Self {
        debug_assert!(axis < 3);
        Self {
            a: split.to_bits(),
            b: axis as u32,
        }
    }

    /// A leaf holding `count` entries of the primitive index array from `offset`.
    #[must_use]
    pub(crate) fn leaf(offset: u32, count: u32) -> Self {
        debug_assert!(count <= MAX_FIELD);
        Self {
            a: offset,
            b: LEAF | (count << 2),
        }
    }

    pub(crate) fn set_above_child(&mut self, index: u32) {
        debug_assert!(index <= MAX_FIELD && !self.is_leaf());
        self.b = (self.b & 3) | (index << 2);
    }

    /// The node moved into a larger array: child indices grow by
    /// `node_offset`, leaf list offsets by `prim_offset`.
    pub(crate) fn shifted(self, node_offset: u32, prim_offset: u32) -> Option<Self> {
        if self.is_leaf() {
            Some(Self {
                a: self.a.checked_add(prim_offset)?,
                b: self.b,
            })
        } else {
            let above = self
                .above_child()
                .checked_add(node_offset)
                .filter(|&a| a <= MAX_FIELD)?;
            Some(Self {
                a: self.a,
                b: (self.b & 3) | (above << 2),
            })
        }
    }

    /// `true` for a leaf.
    #[inline]
    #[must_use]
    pub fn is_leaf(self) -> bool {
        self.b & 3 == LEAF
    }

    /// Split axis of an interior node.
    #[inline]
    #[must_use]
    pub fn axis(self) -> usize {
        (self.b & 3) as usize
    }

    /// Split position of an interior node.
    #[inline]
    #[must_use]
    pub fn split(self) -> f32 {
        f32::from_bits(self.a)
    }

    /// Index of the above child of an interior node.
    #[inline]
    #[must_use]
    pub fn above_child(self) -> u32 {
        self.b >> 2
    }

    /// Primitive count of a leaf.
    #[inline]
    #[must_use]
    pub fn prim_count(self) -> u32 {
        self.b >> 2
    }

    /// Offset of a leaf's list in the primitive index array.
    #[inline]
    #[must_use]
    pub fn prim_offset(self) -> u32 {
        self.a
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_round_trip() {
        let mut n = KdNode::interior(2, -1.5);
        n.set_above_child(MAX_FIELD);
        assert!(!n.is_leaf());
        assert_eq!((n.axis(), n.split(), n.above_child()), (2, -1.5, MAX_FIELD));
        let l = KdNode::leaf(123, 7);
        assert!(l.is_leaf());
        assert_eq!((l.prim_offset(), l.prim_count()), (123, 7));
    }
}

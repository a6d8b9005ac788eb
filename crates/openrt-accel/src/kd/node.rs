//! The compact 8-byte kd-tree node (after pbrt-v4's `KdTreeNode`).

/// Deepest tree any builder may produce; sizes the traversal stack.
pub const MAX_DEPTH: usize = 64;

/// Flag value of the low two bits that marks a leaf.
const LEAF: u32 = 3;

/// Largest primitive count (or instance id) that fits in a leaf's 30 upper bits.
pub(crate) const MAX_FIELD: u32 = (1 << 30) - 1;

/// Largest node index that fits in an interior node's 29 upper bits.
pub(crate) const MAX_NODES: u32 = (1 << 29) - 1;

/// Bit of an interior node's `b` set when its below cell is empty and left out.
const BELOW_EMPTY: u32 = 4;

/// The error of a tree whose node count outgrows [`MAX_NODES`] or whose
/// leaf references outgrow their 32-bit offsets or [`MAX_FIELD`].
pub(crate) const fn too_many_nodes() -> crate::error::AccelError {
    crate::error::AccelError::TooManyNodes {
        limit: MAX_NODES as usize,
    }
}

/// A kd-tree node in 8 bytes.
///
/// - interior: `a` holds the split position's bits, the low two bits of `b`
///   the split axis (0, 1, 2), bit 2 says that the *below* cell is empty and
///   has no node, and the upper 29 bits hold the index of the *above* child,
///   0 when the above cell is empty and has no node (0 is the root, never a
///   child). The below child, when it has a node, is implicitly the next
///   node; when it has none, the above child is the next node.
/// - leaf: the low two bits of `b` are 3, its upper bits the primitive count,
///   and `a` the offset of the leaf's list in the tree's primitive index array.
///
/// Builders emit every empty cell as an empty leaf; object trees then drop
/// them (`elide_empty_leaves`) so that traversal never steps into one.
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
) -> Result<(), crate::error::AccelError> {
    let (at, prim_at) = (nodes.len(), prims.len());
    if prim_at + sub_prims.len() > u32::MAX as usize || at + sub_nodes.len() > MAX_NODES as usize {
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
) -> Result<(), crate::error::AccelError> {
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
) -> Result<(), crate::error::AccelError> {
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
        debug_assert!(index <= MAX_NODES && !self.is_leaf());
        self.b = (self.b & (3 | BELOW_EMPTY)) | (index << 3);
    }

    /// The node moved into a larger array: child indices grow by
    /// `node_offset`, leaf list offsets by `prim_offset`.
    pub(crate) fn shifted(self, node_offset: u32, prim_offset: u32) -> Option<Self> {
        if self.is_leaf() {
            Some(Self {
                a: self.a.checked_add(prim_offset)?,
                b: self.b,
            })
        } else if self.above_child() == 0 {
            Some(self)
        } else {
            let above = self
                .above_child()
                .checked_add(node_offset)
                .filter(|&a| a <= MAX_NODES)?;
            let mut n = self;
            n.set_above_child(above);
            Some(n)
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

    /// Index of the above child of an interior node; 0 when the above
    /// cell is empty and has no node.
    #[inline]
    #[must_use]
    pub fn above_child(self) -> u32 {
        self.b >> 3
    }

    /// `true` when the below cell of an interior node is empty and has no
    /// node (the next node is then the above child).
    #[inline]
    #[must_use]
    pub fn below_empty(self) -> bool {
        self.b & BELOW_EMPTY != 0
    }

    /// The below and above children of the interior node at `index`, `None`
    /// for an empty cell without a node.
    #[must_use]
    pub fn children(self, index: u32) -> [Option<u32>; 2] {
        let below = (!self.below_empty()).then_some(index + 1);
        let above = Some(self.above_child()).filter(|&a| a != 0);
        [below, above]
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

/// Drops the empty leaves of a depth-first tree: an interior node whose
/// below or above cell is an empty leaf gets the matching flag instead of a
/// child, and one whose two cells are both empty becomes an empty leaf
/// itself (then dropped from its parent in turn). A tree that is one empty
/// leaf stays as it is. Leaf offsets are unchanged.
///
/// PERF: a traversal step into an empty leaf is a node load and an
/// unpredictable leaf test for nothing; about half the leaves of an SAH
/// tree are empty (its empty-space cuts). Dropping them took a random ray
/// through a 10k-triangle mesh from 457 to 417 ns (docs/PERFORMANCE.md).
pub(crate) fn elide_empty_leaves(nodes: &[KdNode]) -> Result<Vec<KdNode>, crate::error::AccelError> {
    /// Appends the subtree at `i` without its empty leaves; `false` when it is empty.
    fn emit(nodes: &[KdNode], i: usize, out: &mut Vec<KdNode>) -> Result<bool, crate::error::AccelError> {
        let n = nodes[i];
        if n.is_leaf() {
            if n.prim_count() == 0 {
                return Ok(false);
            }
            out.push(n);
            return Ok(true);
        }
        let at = out.len();
        if at >= MAX_NODES as usize {
            return Err(too_many_nodes());
        }
        out.push(KdNode::interior(n.axis(), n.split()));
        let below = emit(nodes, i + 1, out)?;
        let above_at = out.len() as u32;
        let above = emit(nodes, n.above_child() as usize, out)?;
        if !below && !above {
            out.truncate(at);
            return Ok(false);
        }
        if !below {
            out[at].b |= BELOW_EMPTY;
        }
        if above {
            out[at].set_above_child(above_at);
        }
        Ok(true)
    }
    let mut out = Vec::with_capacity(nodes.len());
    if !nodes.is_empty() && !emit(nodes, 0, &mut out)? {
        out.push(KdNode::leaf(0, 0));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_round_trip() {
        let mut n = KdNode::interior(2, -1.5);
        n.set_above_child(MAX_NODES);
        assert!(!n.is_leaf());
        assert_eq!((n.axis(), n.split(), n.above_child()), (2, -1.5, MAX_NODES));
        assert!(!n.below_empty());
        n.b |= BELOW_EMPTY;
        n.set_above_child(7);
        assert_eq!((n.axis(), n.above_child(), n.below_empty()), (2, 7, true));
        assert_eq!(n.children(6), [None, Some(7)]);
        assert_eq!(
            n.shifted(10, 0).map(|m| (m.above_child(), m.below_empty())),
            Some((17, true))
        );
        let l = KdNode::leaf(123, 7);
        assert!(l.is_leaf());
        assert_eq!((l.prim_offset(), l.prim_count()), (123, 7));
    }

    /// A depth-first tree of `(axis, split)` interiors and leaf counts.
    fn tree(spec: &[Option<u32>], above: &[(usize, u32)]) -> Vec<KdNode> {
        let mut nodes: Vec<KdNode> = spec
            .iter()
            .map(|s| s.map_or(KdNode::interior(0, 0.5), |c| KdNode::leaf(0, c)))
            .collect();
        for &(i, a) in above {
            nodes[i].set_above_child(a);
        }
        nodes
    }

    #[test]
    fn empty_leaves_are_dropped_and_flagged() {
        // 0: split -> 1: split (2: empty, 3: leaf 5) ; 4: empty
        let t = tree(&[None, None, Some(0), Some(5), Some(0)], &[(0, 4), (1, 3)]);
        let e = elide_empty_leaves(&t).unwrap();
        assert_eq!(e.len(), 3);
        assert_eq!(e[0].children(0), [Some(1), None]);
        assert_eq!(e[1].children(1), [None, Some(2)]);
        assert!(e[2].is_leaf() && e[2].prim_count() == 5);
        // The next node after the flagged one is its above child.
        let t = tree(&[None, Some(0), None, Some(0), Some(2), Some(0)], &[(0, 2), (2, 4)]);
        let e = elide_empty_leaves(&t).unwrap();
        assert_eq!(e.len(), 3);
        assert_eq!(e[0].children(0), [None, Some(1)]);
        assert_eq!(e[1].children(1), [None, Some(2)]);
        assert_eq!(e[2].prim_count(), 2);
    }

    #[test]
    fn an_interior_node_over_two_empty_cells_goes_too() {
        // 0: split -> 1: split (2: empty, 3: empty) ; 4: leaf 1
        let t = tree(&[None, None, Some(0), Some(0), Some(1)], &[(0, 4), (1, 3)]);
        let e = elide_empty_leaves(&t).unwrap();
        assert_eq!(e.len(), 2);
        assert_eq!(e[0].children(0), [None, Some(1)]);
        // A tree with nothing in it is one empty leaf.
        let t = tree(&[None, Some(0), Some(0)], &[(0, 2)]);
        assert_eq!(elide_empty_leaves(&t).unwrap(), vec![KdNode::leaf(0, 0)]);
        assert_eq!(
            elide_empty_leaves(&[KdNode::leaf(0, 0)]).unwrap(),
            vec![KdNode::leaf(0, 0)]
        );
        assert!(elide_empty_leaves(&[]).unwrap().is_empty());
    }
}

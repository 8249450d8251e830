//! The 8-byte kd-tree node (thesis 3.2.1, compacted as its reference [20] suggests).
//!
//! ```text
//! inner node: word0 = split position (f32 bits)   word1 = left_child << 2 | axis (0, 1, 2)
//! leaf:       word0 = first triangle reference    word1 = triangle count << 2 | 3
//! ```
//! Children are adjacent: the right child of an inner node is `left_child + 1`, so both are
//! fetched with one cache line. A leaf's triangles are `prim_refs[first .. first + count]` in
//! the tree's one contiguous reference array.

/// The `axis` value that marks a leaf.
const LEAF_TAG: u32 = 3;

/// The largest child index or triangle count a node can hold (30 bits).
pub const MAX_NODE_FIELD: u32 = (1 << 30) - 1;

/// One kd-tree node, inner or leaf, in 8 bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(C)]
pub struct KdNode {
    word0: u32,
    word1: u32,
}

const _: () = assert!(std::mem::size_of::<KdNode>() == 8);

impl KdNode {
    /// An inner node splitting `axis` (0 = x, 1 = y, 2 = z) at `split`, whose children are
    /// `left_child` (below the plane) and `left_child + 1` (above).
    ///
    /// # Panics
    /// If `axis > 2` or `left_child > MAX_NODE_FIELD` (the builder checks both first).
    #[inline]
    pub fn inner(axis: u32, split: f32, left_child: u32) -> KdNode {
        assert!(axis < 3 && left_child <= MAX_NODE_FIELD);
        KdNode { word0: split.to_bits(), word1: (left_child << 2) | axis }
    }

    /// A leaf holding `count` triangle references starting at `first_ref`.
    ///
    /// # Panics
    /// If `count > MAX_NODE_FIELD` (the builder checks it first).
    #[inline]
    pub fn leaf(first_ref: u32, count: u32) -> KdNode {
        assert!(count <= MAX_NODE_FIELD);
        KdNode { word0: first_ref, word1: (count << 2) | LEAF_TAG }
    }

    /// True for a leaf.
    #[inline(always)]
    pub fn is_leaf(self) -> bool {
        self.word1 & 3 == LEAF_TAG
    }

    /// Split axis of an inner node (0, 1 or 2); 3 for a leaf.
    #[inline(always)]
    pub fn axis(self) -> usize {
        (self.word1 & 3) as usize
    }

    /// Split position of an inner node.
    #[inline(always)]
    pub fn split(self) -> f32 {
        f32::from_bits(self.word0)
    }

    /// Index of the left (below) child of an inner node; the right child follows it.
    #[inline(always)]
    pub fn left_child(self) -> usize {
        (self.word1 >> 2) as usize
    }

    /// First index into the reference array of a leaf.
    #[inline(always)]
    pub fn first_ref(self) -> usize {
        self.word0 as usize
    }

    /// Number of triangles in a leaf.
    #[inline(always)]
    pub fn prim_count(self) -> usize {
        (self.word1 >> 2) as usize
    }

    /// The two raw words `(word0, word1)` (for hashing and determinism checks).
    #[inline]
    pub fn raw(self) -> (u32, u32) {
        (self.word0, self.word1)
    }

    /// The reference range `first .. first + count` of a leaf.
    #[inline(always)]
    pub fn prim_range(self) -> std::ops::Range<usize> {
        let first = self.first_ref();
        first..first + self.prim_count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips() {
        let n = KdNode::inner(2, -1.5, 12345);
        assert!(!n.is_leaf());
        assert_eq!((n.axis(), n.split(), n.left_child()), (2, -1.5, 12345));
        let n = KdNode::inner(0, -0.0, MAX_NODE_FIELD);
        assert_eq!(n.split().to_bits(), (-0.0f32).to_bits());
        assert_eq!(n.left_child(), MAX_NODE_FIELD as usize);
        let l = KdNode::leaf(u32::MAX, MAX_NODE_FIELD);
        assert!(l.is_leaf());
        assert_eq!((l.first_ref(), l.prim_count()), (u32::MAX as usize, MAX_NODE_FIELD as usize));
    }

    #[test]
    #[should_panic]
    fn child_index_overflow_is_caught() {
        let _ = KdNode::inner(1, 0.0, MAX_NODE_FIELD + 1);
    }
}

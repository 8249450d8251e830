//! The one kd-tree descent: the loop every kd-tree kernel of the workspace runs (thesis
//! Listing 2.1, and its packet, frustum and cone forms of Listings 2.4, 4.1-4.3).
//!
//! Every kernel walks the tree the same way: read a node; at an inner node decide which
//! children the ray group enters, entering one and deferring the other on a stack; at a leaf
//! visit the leaf's triangles; when a subtree is done, pop the next deferred voxel, which the
//! group may drop (its rays have all hit something closer). What differs between a single
//! ray, a 2x2 packet, a frustum, four MFT frusta, a cone, edge widths and shadow frusta is
//! only:
//! - **the ray group and its interval in a voxel** ([`Descent::Span`], what is carried down,
//!   and [`Descent::Deferred`], what is pushed): one `[t0, t1]` for a single ray, one per lane
//!   for a packet or for the frusta of MFT, a parameter interval of a swept box for a shadow
//!   frustum. Its width (one ray, four lanes, eight) is the type's, so a kernel at another
//!   SIMD width is another `Span` type, not another loop;
//! - **the per-node interval step** ([`Descent::inner`]): the plane distance and the
//!   front/back/both decision;
//! - **the leaf visitor** ([`Descent::leaf`]): triangle tests, culling, pairing;
//! - **the pop rule** ([`Descent::resume`]): the deferred interval clamped to the closest hit.
//!
//! [`descend`] is the loop, written once. It is `#[inline(always)]` and generic, so each
//! kernel gets its own monomorphic copy with no dynamic dispatch, allocation or lock inside:
//! the hooks inline into the loop and their state lives in registers, as in a hand-written
//! kernel. [`Descent::enter`] is an optional hook before a node is read, for groups that
//! split themselves on the way down (Benthin & Wald's frusta of blocks of rays) or drop out
//! (lanes whose rays are all blocked).
//!
//! The stack is the caller's ([`Deferrals`]): the fixed [`Stack`] of the kernels whose depth
//! the tree bounds, or a `Vec` kept between calls by the kernels that can push more than one
//! voxel per node (a block of rays split into its children).

use crate::counters::Counters;
use crate::node::KdNode;
use crate::stack::Stack;
use crate::tree::KdTree;

/// A voxel deferred for later: the node and what the group carries into it.
#[derive(Clone, Copy, Debug)]
pub struct Entry<T> {
    /// The node index.
    pub node: u32,
    /// The group's interval (and box, or anything else) in it.
    pub value: T,
}

/// Where an inner node sends the group ([`Descent::inner`]).
#[derive(Clone, Copy, Debug)]
pub enum Visit<T> {
    /// Enter `node` next, with the span as the step left it.
    One(usize),
    /// Enter `first` next, with the span as the step left it, and defer `second` with
    /// `deferred`.
    Both {
        /// The child entered now.
        first: usize,
        /// The child deferred.
        second: usize,
        /// What the group carries into `second`.
        deferred: T,
    },
    /// Enter neither child: go on with the next deferred voxel.
    Neither,
}

/// Whether the walk goes on after a leaf.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Flow {
    /// Go on with the next deferred voxel.
    Continue,
    /// Stop: the group is done (an any-hit ray blocked, every ray finished).
    Stop,
}

/// A stack of deferred voxels: [`Stack`] (fixed, uninitialised slots) or a reused `Vec`.
pub trait Deferrals<T: Copy> {
    /// Pushes a voxel.
    fn push(&mut self, entry: Entry<T>);
    /// Pops the last voxel pushed.
    fn pop(&mut self) -> Option<Entry<T>>;
    /// The last voxel pushed, left on the stack.
    fn top(&self) -> Option<Entry<T>>;
}

impl<T: Copy> Deferrals<T> for Stack<Entry<T>> {
    #[inline(always)]
    fn push(&mut self, entry: Entry<T>) {
        Stack::push(self, entry)
    }
    #[inline(always)]
    fn pop(&mut self) -> Option<Entry<T>> {
        Stack::pop(self)
    }
    #[inline(always)]
    fn top(&self) -> Option<Entry<T>> {
        Stack::top(self)
    }
}

impl<T: Copy> Deferrals<T> for Vec<Entry<T>> {
    #[inline(always)]
    fn push(&mut self, entry: Entry<T>) {
        Vec::push(self, entry)
    }
    #[inline(always)]
    fn pop(&mut self) -> Option<Entry<T>> {
        Vec::pop(self)
    }
    #[inline(always)]
    fn top(&self) -> Option<Entry<T>> {
        self.last().copied()
    }
}

/// A ray group walking the tree: its interval step, its leaf visitor and its pop rule, the
/// three parts in which the kernels differ (see the module documentation).
pub trait Descent {
    /// What the group carries down into the voxel it is in: its interval(s), and the box for
    /// kernels that cull against it.
    type Span: Copy;
    /// What is pushed with a deferred voxel (often the span itself).
    type Deferred: Copy;
    /// The stack of deferred voxels this group uses.
    type Stack: Deferrals<Self::Deferred>;

    /// Before node `index` is read, with the group's span in it: `false` skips the node (the
    /// walk pops the next deferred voxel). The hook of groups that split themselves or drop
    /// lanes on the way down; the default enters every node. `counters` counts what the hook
    /// traces itself (a part of the group handed to another kernel); a skipped node is not
    /// counted.
    #[inline(always)]
    fn enter<C: Counters>(
        &mut self,
        _index: usize,
        _span: &mut Self::Span,
        _stack: &mut Self::Stack,
        _counters: &mut C,
    ) -> bool {
        true
    }

    /// The interval step at inner `node`: which children to enter, `span` updated to the one
    /// entered next.
    fn inner(&mut self, node: KdNode, span: &mut Self::Span, stack: &Self::Stack) -> Visit<Self::Deferred>;

    /// The leaf visitor: the triangles of `node` with the group's `span` in it. `stack` holds
    /// the voxels still to come (the edge-width kernel pairs hits no later voxel can precede).
    fn leaf<C: Counters>(&mut self, node: KdNode, span: &Self::Span, stack: &Self::Stack, counters: &mut C) -> Flow;

    /// The pop rule: the span of a deferred voxel once the group's hits so far are known, or
    /// `None` to drop the voxel (nothing closer can lie in it).
    fn resume(&mut self, deferred: Self::Deferred) -> Option<Self::Span>;
}

/// Walks `tree` from node `start` with the group `group` in `span`, deferring voxels on
/// `stack` (which should be empty), until the group stops or no voxel is left. Counts one
/// node per node read ([`Counters::node`]); leaves and tests are the leaf visitor's to count.
#[inline(always)]
pub fn descend<D: Descent, C: Counters>(
    tree: &KdTree,
    group: &mut D,
    (start, mut span): (usize, D::Span),
    stack: &mut D::Stack,
    counters: &mut C,
) {
    let nodes = tree.nodes();
    let mut index = start;
    loop {
        let entered = group.enter(index, &mut span, stack, counters);
        let next = if !entered {
            None
        } else {
            // SAFETY: `index` is `start` (a node of `tree`: the root, or a node an earlier walk
            // reached), a child of an inner node, or a deferred child pushed by `inner`, and
            // `KdTree`'s invariant (checked by `KdTree::assemble`, through which every tree is
            // made) puts the root and every inner node's children in `nodes`. The bounds check
            // this skips cost 2% of single-ray throughput.
            debug_assert!(index < nodes.len());
            let node = unsafe { *nodes.get_unchecked(index) };
            counters.node();
            if !node.is_leaf() {
                match group.inner(node, &mut span, stack) {
                    Visit::One(child) => Some(child),
                    Visit::Both { first, second, deferred } => {
                        stack.push(Entry { node: second as u32, value: deferred });
                        Some(first)
                    }
                    Visit::Neither => None,
                }
            } else {
                counters.leaf_visit_start();
                let flow = group.leaf(node, &span, stack, counters);
                counters.leaf_visit_end();
                if flow == Flow::Stop {
                    return;
                }
                None
            }
        };
        if let Some(child) = next {
            index = child;
            continue;
        }
        // Next voxel: pop, skipping those the group drops.
        loop {
            let Some(entry) = stack.pop() else { return };
            if let Some(s) = group.resume(entry.value) {
                (index, span) = (entry.node as usize, s);
                break;
            }
        }
    }
}

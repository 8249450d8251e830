//! The multi-node (Wald, Benthin & Boulos 2008, section 3), written once for every width:
//! [`Node<W>`] holds the boxes of up to `W` children SoA, one lane array per box
//! coordinate, and what each child is.
//!
//! A width is one impl of [`NodeWidth`] on the marker [`Width<W>`]: it fixes the alignment
//! of the lane arrays (one SIMD register each, so a node test loads them aligned) and the
//! capacity of the traversal's stack. Rust cannot compute either from `W` in a generic
//! context, so each width names them once here: 4 (16 bytes, SSE), 8 (32 bytes, AVX2) and 16
//! (64 bytes, the AVX-512 register). The layout is the same as when each width had a type of
//! its own: [`Node4`] is 112 bytes (16-byte aligned), [`Node8`] 224 bytes (32-byte aligned),
//! [`Node16`] 448 bytes (64-byte aligned, one cache line per box coordinate); the lane arrays
//! come first and the child words last.
//!
//! The node tests live beside it: the portable scalar test of every width in
//! [`crate::boxtest`], the SIMD tests in [`crate::simd4`],
//! [`crate::simd8`] and [`crate::simd16`].

use std::fmt::{self, Debug};
use std::mem::MaybeUninit;
use std::ops::{Index, IndexMut};

use glam::Vec3;
use kdtree::Aabb;

/// A child slot with no child.
pub const EMPTY: u32 = u32::MAX;

/// The flag of a leaf child: the rest of the word is its block index.
pub const LEAF: u32 = 1 << 31;

/// The deepest multi-node tree the build makes, of any width (the root alone is depth 1):
/// the build's median fallback keeps the binary depth below `build::MEDIAN_DEPTH + 33`,
/// and a multi-node takes at least one binary level (see [`crate::build`]). The traversal's
/// stacks are sized by it ([`stack_capacity`]).
pub const MAX_DEPTH: u32 = 85;

/// Entries of the traversal's fixed stack for nodes of `width` children: a node pushes at
/// most `width - 1` entries more than it pops, so `(width - 1) * MAX_DEPTH + 1` suffice.
pub const fn stack_capacity(width: usize) -> usize {
    (width - 1) * MAX_DEPTH as usize + 1
}

/// The node width `W` as a type, to name what each width fixes ([`NodeWidth`]).
#[derive(Clone, Copy, Debug, Default)]
pub struct Width<const W: usize>;

/// What a node width fixes beyond `W`: the lane arrays' alignment and the traversal stack.
/// Implemented for 4, 8 and 16; a width without an impl has no node.
pub trait NodeWidth {
    /// A zero-sized type of the lane arrays' alignment: `4 W` bytes, one SIMD register.
    type Align: Copy + Debug + Default + Send + Sync + 'static;
    /// The traversal's stack of entries `T`: [`stack_capacity`]`(W)` of them, uninitialised.
    type Stack<T: Copy>: StackArray<T>;
}

/// Zero-sized, 16-byte aligned: the lanes of a 4-wide node (one SSE register).
#[derive(Clone, Copy, Debug, Default)]
#[repr(align(16))]
pub struct Align16;

/// Zero-sized, 32-byte aligned: the lanes of an 8-wide node (one AVX register).
#[derive(Clone, Copy, Debug, Default)]
#[repr(align(32))]
pub struct Align32;

/// Zero-sized, 64-byte aligned: the lanes of a 16-wide node (one AVX-512 register).
#[derive(Clone, Copy, Debug, Default)]
#[repr(align(64))]
pub struct Align64;

impl NodeWidth for Width<4> {
    type Align = Align16;
    type Stack<T: Copy> = [MaybeUninit<T>; stack_capacity(4)];
}

impl NodeWidth for Width<8> {
    type Align = Align32;
    type Stack<T: Copy> = [MaybeUninit<T>; stack_capacity(8)];
}

impl NodeWidth for Width<16> {
    type Align = Align64;
    type Stack<T: Copy> = [MaybeUninit<T>; stack_capacity(16)];
}

/// A traversal stack's storage: a fixed array left uninitialised (only the entries below the
/// stack pointer are ever read, after being written).
pub trait StackArray<T>: Sized {
    /// The array, every entry uninitialised.
    fn uninit() -> Self;
    /// Its entries.
    fn entries(&mut self) -> &mut [MaybeUninit<T>];
}

impl<T, const N: usize> StackArray<T> for [MaybeUninit<T>; N] {
    #[inline(always)]
    fn uninit() -> Self {
        [const { MaybeUninit::uninit() }; N]
    }

    #[inline(always)]
    fn entries(&mut self) -> &mut [MaybeUninit<T>] {
        self
    }
}

/// One box coordinate of the `W` children: `W` floats aligned for one `4 W`-byte load.
#[derive(Clone, Copy)]
#[repr(C)]
pub struct Lanes<const W: usize>
where
    Width<W>: NodeWidth,
{
    lanes: [f32; W],
    _align: <Width<W> as NodeWidth>::Align,
}

impl<const W: usize> Lanes<W>
where
    Width<W>: NodeWidth,
{
    /// `x` in every lane.
    pub fn splat(x: f32) -> Lanes<W> {
        Lanes { lanes: [x; W], _align: Default::default() }
    }

    /// The lanes.
    #[inline(always)]
    pub fn as_array(&self) -> &[f32; W] {
        &self.lanes
    }

    /// The lanes, to write.
    #[inline(always)]
    pub fn as_mut_array(&mut self) -> &mut [f32; W] {
        &mut self.lanes
    }
}

impl<const W: usize> Index<usize> for Lanes<W>
where
    Width<W>: NodeWidth,
{
    type Output = f32;

    #[inline(always)]
    fn index(&self, i: usize) -> &f32 {
        &self.lanes[i]
    }
}

impl<const W: usize> IndexMut<usize> for Lanes<W>
where
    Width<W>: NodeWidth,
{
    #[inline(always)]
    fn index_mut(&mut self, i: usize) -> &mut f32 {
        &mut self.lanes[i]
    }
}

impl<const W: usize> Debug for Lanes<W>
where
    Width<W>: NodeWidth,
{
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.lanes.fmt(f)
    }
}

/// A multi-node of `W` children: their boxes SoA and what each child is.
#[derive(Clone, Copy, Debug)]
#[repr(C)]
pub struct Node<const W: usize>
where
    Width<W>: NodeWidth,
{
    /// Per axis `[min, max]`, each over the `W` children.
    pub bounds: [[Lanes<W>; 2]; 3],
    /// Per slot: [`EMPTY`], a leaf (`LEAF | block`) or the index of an inner node.
    pub child: [u32; W],
}

/// The 4-wide node: one SSE register per box coordinate, 112 bytes.
pub type Node4 = Node<4>;

/// The 8-wide node: one AVX register per box coordinate, 224 bytes.
pub type Node8 = Node<8>;

/// The 16-wide node, the paper's (section 3): one AVX-512 register per box coordinate, 448
/// bytes.
pub type Node16 = Node<16>;

const _: () = assert!(size_of::<Node4>() == 112 && align_of::<Node4>() == 16);
const _: () = assert!(size_of::<Node8>() == 224 && align_of::<Node8>() == 32);
const _: () = assert!(size_of::<Node16>() == 448 && align_of::<Node16>() == 64);

impl<const W: usize> Node<W>
where
    Width<W>: NodeWidth,
{
    /// A node with every slot empty (`min = +inf`, `max = -inf`: no ray enters them).
    pub fn empty() -> Node<W> {
        let (inf, ninf) = (Lanes::splat(f32::INFINITY), Lanes::splat(f32::NEG_INFINITY));
        Node { bounds: [[inf, ninf]; 3], child: [EMPTY; W] }
    }

    /// Sets slot `i` to `child` with box `b`.
    pub fn set(&mut self, i: usize, child: u32, b: &Aabb) {
        for axis in 0..3 {
            self.bounds[axis][0][i] = b.min[axis];
            self.bounds[axis][1][i] = b.max[axis];
        }
        self.child[i] = child;
    }

    /// The box of slot `i` (empty for an empty slot).
    pub fn child_box(&self, i: usize) -> Aabb {
        let c = |k: usize| Vec3::new(self.bounds[0][k][i], self.bounds[1][k][i], self.bounds[2][k][i]);
        Aabb { min: c(0), max: c(1) }
    }
}

/// A multi-node as the build, `validate` and the traversal see it: implemented by
/// [`Node<W>`] for every width with a [`NodeWidth`].
pub trait MultiNode: Copy + Debug + Send + Sync + 'static {
    /// Child slots per node.
    const WIDTH: usize;
    /// The traversal's stack for this width ([`NodeWidth::Stack`]).
    type Stack<T: Copy>: StackArray<T>;
    /// A node with every slot empty.
    fn empty() -> Self;
    /// Sets slot `i` to `child` with box `b`.
    fn set(&mut self, i: usize, child: u32, b: &Aabb);
    /// The box of slot `i` (empty for an empty slot).
    fn child_box(&self, i: usize) -> Aabb;
    /// Per slot: [`EMPTY`], a leaf (`LEAF | block`) or the index of an inner node.
    fn children(&self) -> &[u32];
}

impl<const W: usize> MultiNode for Node<W>
where
    Width<W>: NodeWidth,
{
    const WIDTH: usize = W;
    type Stack<T: Copy> = <Width<W> as NodeWidth>::Stack<T>;

    fn empty() -> Node<W> {
        Node::empty()
    }

    fn set(&mut self, i: usize, child: u32, b: &Aabb) {
        Node::set(self, i, child, b);
    }

    fn child_box(&self, i: usize) -> Aabb {
        Node::child_box(self, i)
    }

    #[inline(always)]
    fn children(&self) -> &[u32] {
        &self.child
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn set_and_read_back<const W: usize>()
    where
        Width<W>: NodeWidth,
    {
        let mut n = Node::<W>::empty();
        assert!((0..W).all(|i| n.child_box(i).is_empty() && n.children()[i] == EMPTY));
        for i in 0..W {
            let b = Aabb { min: Vec3::new(i as f32, -1.0, 2.0), max: Vec3::new(i as f32 + 0.5, 3.0, 2.0) };
            n.set(i, i as u32 | LEAF, &b);
            assert_eq!(n.child_box(i), b);
        }
        assert_eq!(n.children(), (0..W as u32).map(|i| i | LEAF).collect::<Vec<_>>());
        // The lane arrays are aligned for one register load each.
        for planes in &n.bounds {
            for lanes in planes {
                assert_eq!(lanes.as_array().as_ptr() as usize % (4 * W), 0);
            }
        }
    }

    #[test]
    fn every_width_sets_and_reads_back_its_slots() {
        set_and_read_back::<4>();
        set_and_read_back::<8>();
        set_and_read_back::<16>();
    }

    #[test]
    fn stacks_hold_a_full_descent() {
        assert_eq!(stack_capacity(8), 596);
        let mut s = <Node8 as MultiNode>::Stack::<u32>::uninit();
        assert_eq!(s.entries().len(), (Node8::WIDTH - 1) * MAX_DEPTH as usize + 1);
        assert_eq!(<Node<16> as MultiNode>::Stack::<(u32, f32)>::uninit().entries().len(), stack_capacity(16));
    }
}

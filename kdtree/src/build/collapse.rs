//! Retraction of bad splits ([`super::BuildConfig::collapse`]; Mitsuba's `gkdtree` retracts
//! the splits that did not lower the cost): a pass over the built tree, bottom up, that
//! turns every subtree whose SAH cost is at least the cost of one leaf of its distinct
//! triangles into that leaf.
//!
//! - The SAH cost of a subtree (thesis 2.2.1, with the build's terms): a leaf of `n`
//!   triangles costs [`Costs::leaf`] (`C_isect * ceil(n / W)`); an inner node
//!   `(C_trav + (SA_l cost_l + SA_r cost_r) / SA) * f`, `f` the empty factor when a child is an
//!   empty leaf, as the build priced its split. Children are collapsed first, so a node
//!   compares the cost of its subtree as it will be.
//! - Without bad refines every split was cheaper than its leaf with its children taken as
//!   leaves, and each child's subtree costs at most its leaf, so nothing collapses but for
//!   rounding or a binned node's estimate; the pass undoes the bad refines that did not pay.
//! - A subtree's distinct triangles are gathered (and sorted) only when its cost is at least
//!   the leaf of its largest leaf, a lower bound of the collapsed leaf's cost.
//! - The new arrays keep the builder's layout (a node's two children adjacent, then the left
//!   subtree, then the right; references in leaf order), their bytes taken from the meter.

use super::sah::{Costs, surface_area64};
use super::{BuildError, BuiltNodes, Meter, inner_node, leaf_node};
use crate::{Aabb, KdNode};

/// What the bottom-up pass knows of a subtree.
struct Eval {
    /// SAH cost of the subtree (collapsed where it collapses), in its box.
    cost: f64,
    /// The most triangles of one of its leaves.
    max_leaf: usize,
    /// An empty leaf.
    empty: bool,
    /// Some node in it collapses.
    any: bool,
}

/// The tree `built` (over `bounds`) with its costlier subtrees collapsed into leaves (see the
/// module docs); `built` itself when none is.
pub(crate) fn collapse(
    built: BuiltNodes,
    bounds: Aabb,
    costs: &Costs,
    meter: &Meter,
) -> Result<BuiltNodes, BuildError> {
    let (old_nodes, old_refs) = (built.nodes.len() as u64, built.prim_refs.len() as u64);
    meter.take(old_nodes, "the collapse's node flags")?;
    let mut retract = vec![false; built.nodes.len()];
    let mut scratch = Vec::new();
    let any = eval(&built, 0, bounds, costs, &mut retract, &mut scratch).any;
    if !any {
        meter.give(old_nodes);
        return Ok(built);
    }
    // At most the old sizes; settled to the actual ones below.
    let upper = 8 * old_nodes + 4 * old_refs;
    if let Err(e) = meter.take(upper, "the collapsed tree's arrays") {
        meter.give(old_nodes);
        return Err(e);
    }
    let mut out = BuiltNodes {
        nodes: Vec::with_capacity(built.nodes.len()),
        prim_refs: Vec::with_capacity(built.prim_refs.len()),
    };
    out.nodes.push(KdNode::leaf(0, 0));
    let done = emit(&built, 0, 0, &retract, &mut out, &mut scratch);
    out.nodes.shrink_to_fit();
    out.prim_refs.shrink_to_fit();
    let now = 8 * out.nodes.len() as u64 + 4 * out.prim_refs.len() as u64;
    drop(built);
    meter.give(old_nodes + upper - now + 8 * old_nodes + 4 * old_refs);
    done?;
    Ok(out)
}

/// The bottom-up pass over node `i` in box `b`: its cost, with `retract` set on the nodes
/// that collapse.
fn eval(t: &BuiltNodes, i: usize, b: Aabb, costs: &Costs, retract: &mut [bool], scratch: &mut Vec<u32>) -> Eval {
    let node = t.nodes[i];
    if node.is_leaf() {
        let n = node.prim_count();
        return Eval { cost: costs.leaf(n), max_leaf: n, empty: n == 0, any: false };
    }
    let (k, p, c) = (node.axis(), node.split(), node.left_child());
    let (mut bl, mut br) = (b, b);
    bl.max[k] = p;
    br.min[k] = p;
    let l = eval(t, c, bl, costs, retract, scratch);
    let r = eval(t, c + 1, br, costs, retract, scratch);
    let sa = surface_area64(&b);
    let (wl, wr) = if sa > 0.0 { (surface_area64(&bl) / sa, surface_area64(&br) / sa) } else { (1.0, 1.0) };
    let f = if l.empty || r.empty { costs.empty_factor } else { 1.0 };
    let cost = (costs.c_trav + wl * l.cost + wr * r.cost) * f;
    let max_leaf = l.max_leaf.max(r.max_leaf);
    if cost >= costs.leaf(max_leaf) {
        let n = distinct(t, i, scratch);
        let leaf = costs.leaf(n);
        if cost >= leaf {
            retract[i] = true;
            return Eval { cost: leaf, max_leaf: n, empty: n == 0, any: true };
        }
    }
    Eval { cost, max_leaf, empty: false, any: l.any || r.any }
}

/// The distinct triangles of the leaves under node `i`, ascending, in `out`; their count.
fn distinct(t: &BuiltNodes, i: usize, out: &mut Vec<u32>) -> usize {
    out.clear();
    let mut stack = vec![i];
    while let Some(j) = stack.pop() {
        let n = t.nodes[j];
        if n.is_leaf() {
            out.extend_from_slice(&t.prim_refs[n.first_ref()..n.first_ref() + n.prim_count()]);
        } else {
            stack.extend([n.left_child() + 1, n.left_child()]);
        }
    }
    out.sort_unstable();
    out.dedup();
    out.len()
}

/// Writes node `i` of `t` to `out.nodes[slot]`, and its subtree after: a leaf where
/// `retract` says.
fn emit(
    t: &BuiltNodes,
    i: usize,
    slot: usize,
    retract: &[bool],
    out: &mut BuiltNodes,
    scratch: &mut Vec<u32>,
) -> Result<(), BuildError> {
    let node = t.nodes[i];
    if retract[i] {
        let n = distinct(t, i, scratch);
        let first = out.prim_refs.len();
        out.prim_refs.extend_from_slice(scratch);
        out.nodes[slot] = leaf_node(first, n)?;
    } else if node.is_leaf() {
        let first = out.prim_refs.len();
        out.prim_refs.extend_from_slice(&t.prim_refs[node.first_ref()..node.first_ref() + node.prim_count()]);
        out.nodes[slot] = leaf_node(first, node.prim_count())?;
    } else {
        let c = out.nodes.len();
        out.nodes[slot] = inner_node(node.axis(), node.split(), c)?;
        out.nodes.extend([KdNode::leaf(0, 0); 2]);
        emit(t, node.left_child(), c, retract, out, scratch)?;
        emit(t, node.left_child() + 1, c + 1, retract, out, scratch)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    const COSTS: Costs = Costs { c_trav: 1.0, c_isect: 1.0, empty_factor: 1.0, width: 4.0 };

    /// A root split at x = 4 of the box [0, 8] x [0, 1]^2 into two leaves of 4 triangles each
    /// (each side 18/34 of the root's area): with a leaf width of 4 it costs
    /// 1 + 2 * 18/34 = 2.06, over one leaf of the 8 triangles (2 groups): collapsed. With a
    /// width of 1 it costs 1 + 8 * 18/34 = 5.2, under the leaf's 8: kept.
    #[test]
    fn a_costlier_split_collapses_into_the_leaf_of_its_distinct_triangles() {
        let b = Aabb::new(Vec3::ZERO, Vec3::new(8.0, 1.0, 1.0));
        let tree = || BuiltNodes {
            nodes: vec![KdNode::inner(0, 4.0, 1), KdNode::leaf(0, 4), KdNode::leaf(4, 4)],
            prim_refs: vec![0, 1, 2, 3, 7, 6, 5, 4],
        };
        let meter = Meter::new(None);
        let out = collapse(tree(), b, &COSTS, &meter).unwrap();
        assert_eq!(out.nodes, vec![KdNode::leaf(0, 8)]);
        assert_eq!(out.prim_refs, (0..8).collect::<Vec<u32>>());
        let per_triangle = Costs { width: 1.0, ..COSTS };
        let kept = collapse(tree(), b, &per_triangle, &meter).unwrap();
        assert_eq!(kept.nodes, tree().nodes);
        assert_eq!(kept.prim_refs, tree().prim_refs);
    }

    /// Only the costlier subtree collapses; the layout stays the builder's (children
    /// adjacent, left subtree first) and the references follow the leaves.
    #[test]
    fn a_deeper_subtree_collapses_and_the_rest_is_kept() {
        // Root split at x = 1: the left child a leaf of 4 distinct triangles, the right an
        // inner node split at y = 1 whose leaves share their 2 triangles.
        let b = Aabb::new(Vec3::ZERO, Vec3::new(8.0, 2.0, 2.0));
        let tree = BuiltNodes {
            nodes: vec![
                KdNode::inner(0, 1.0, 1),
                KdNode::leaf(0, 4),
                KdNode::inner(1, 1.0, 3),
                KdNode::leaf(4, 2),
                KdNode::leaf(6, 2),
            ],
            prim_refs: vec![0, 1, 2, 3, 5, 4, 4, 5],
        };
        let costs = Costs { c_trav: 1.0, c_isect: 1.0, empty_factor: 1.0, width: 1.0 };
        let out = collapse(tree, b, &costs, &Meter::new(None)).unwrap();
        assert_eq!(out.nodes, vec![KdNode::inner(0, 1.0, 1), KdNode::leaf(0, 4), KdNode::leaf(4, 2)]);
        assert_eq!(out.prim_refs, vec![0, 1, 2, 3, 4, 5]);
    }
}

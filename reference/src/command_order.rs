//! Distance-sorted commands, front to back (issue 13; E§7 "distance-sorted commands"): the
//! hierarchical cut's coalesced commands reordered by their nearest view depth. The CPU twin of
//! `gpu/src/shaders/command_order.wgsl` (driven by `gpu/src/command_order.rs`), written
//! shader-shaped:
//! 1. *keys*: every raw (uncoalesced) command `j` belongs to run `r(j)` (the number of run heads
//!    up to and including `j`, less one: [`crate::coalesce::is_head`]); run `r`'s key is the
//!    minimum over its commands of [`forestlod_shared::command_depth_key`] of their node's
//!    [`forestlod_shared::node_near_depth`] (an `atomicMin` on the GPU);
//! 2. *sort*: the pairs `(key, r)` sorted ascending (a bitonic sort on the GPU, one dispatch per
//!    merge step, padding pairs `(u32::MAX, slot)` after the real ones). The index breaks ties, so
//!    the order is total: equal keys keep their unsorted order, and the result does not depend on
//!    the sort algorithm;
//! 3. *gather*: output command `i` is run `pairs[i].1`'s command and data with
//!    `base_vertex = i << COMMAND_SHIFT` (the draw stage finds its data through it).
//!
//! Why the key is a valid front-to-back key is said at [`forestlod_shared::command_depth_key`]
//! (`shared/src/cut.rs`): no fragment of a command is nearer than its key.
//!
//! ## Contract (`tests/tests/properties/command_order_properties.rs`,
//! `tests/tests/parity/hier_select.rs`)
//! - The output is a permutation of the input commands (same multiset of (command without
//!   `base_vertex`, data)), with `base_vertex` renumbered to the new slots.
//! - Keys are non-decreasing along the output; equal keys keep their input order.
//! - [`CommandOrder::Node`] is the identity (nothing is computed).
//! - Counters are unchanged (a reorder draws the same instances).

use forestlod_shared::{
    COMMAND_SHIFT, Coalesce, CommandOrder, DrawCommand, NodeMeta, ViewUniform, command_depth_key,
    node_near_depth,
};

use crate::select::Selection;

/// Pass 1: the key of every coalesced command (run) of `coalesced`, the coalescing (under
/// `coalesce`) of `raw`, the cut's list over `nodes` (module docs).
pub fn run_keys(
    nodes: &[NodeMeta],
    raw: &Selection,
    coalesced: &Selection,
    u: &ViewUniform,
    coalesce: Coalesce,
) -> Vec<u32> {
    let mut keys = vec![u32::MAX; coalesced.commands.len()];
    let mut run = 0usize;
    for (j, d) in raw.data.iter().enumerate() {
        if j > 0 && crate::coalesce::is_head(raw, j, coalesce) {
            run += 1;
        }
        let key = command_depth_key(node_near_depth(u, &nodes[d.batch as usize]));
        keys[run] = keys[run].min(key);
    }
    keys
}

/// Passes 2 and 3: `s` reordered by `keys` (one per command) under `order`, and the keys in the
/// output order (module docs).
pub fn order(s: Selection, keys: Vec<u32>, order: CommandOrder) -> (Selection, Vec<u32>) {
    if order == CommandOrder::Node {
        return (s, keys);
    }
    let mut pairs: Vec<(u32, u32)> = keys.iter().zip(0u32..).map(|(&k, i)| (k, i)).collect();
    pairs.sort_unstable();
    let mut out = Selection {
        counters: s.counters,
        ..Selection::default()
    };
    for (slot, &(_, i)) in pairs.iter().enumerate() {
        out.commands.push(DrawCommand {
            base_vertex: (slot as i32) << COMMAND_SHIFT,
            ..s.commands[i as usize]
        });
        out.data.push(s.data[i as usize]);
    }
    (out, pairs.iter().map(|p| p.0).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use forestlod_shared::CommandData;

    fn selection(n: usize) -> Selection {
        let mut s = Selection::default();
        for i in 0..n {
            s.commands.push(DrawCommand {
                index_count: 6,
                instance_count: 1,
                first_index: 0,
                base_vertex: (i as i32) << COMMAND_SHIFT,
                first_instance: 10 * i as u32,
            });
            s.data.push(CommandData {
                batch: i as u32,
                ..bytemuck::Zeroable::zeroed()
            });
        }
        s.counters.commands = n as u32;
        s
    }

    #[test]
    fn sorts_by_key_then_index_and_renumbers() {
        let s = selection(4);
        let (out, keys) = order(s.clone(), vec![5, 2, 5, 0], CommandOrder::FrontToBack);
        let batches: Vec<u32> = out.data.iter().map(|d| d.batch).collect();
        assert_eq!(batches, [3, 1, 0, 2]);
        assert_eq!(keys, [0, 2, 5, 5]);
        for (i, c) in out.commands.iter().enumerate() {
            assert_eq!(c.base_vertex >> COMMAND_SHIFT, i as i32);
        }
        assert_eq!(out.counters, s.counters);
        let (same, _) = order(s.clone(), vec![5, 2, 5, 0], CommandOrder::Node);
        assert_eq!(same, s);
    }
}

//! Properties of the reference pipeline (CPU only), one test binary: random scenes, cameras and
//! parameters checked against oracles, and the numerical extremes.
//! - [`select_properties`]: grouped selection against the per-tree oracle;
//! - [`refine_properties`]: the `refine` stage against the per-tree oracle, refined frames
//!   against unrefined ones;
//! - [`hierarchy_properties`]: hierarchies (issue 13) and their cut against the per-tree oracle
//!   and the grid, frames against the grid's;
//! - [`coalesce_properties`]: command coalescing of the hierarchical cut (issue 13) against the
//!   uncoalesced commands;
//! - [`command_order_properties`]: the front-to-back command order (issue 13, E§7) against the
//!   node order;
//! - [`tree_assembly_properties`]: the tree draw's input assembly in pieces (issue 14) against
//!   the plain multi-draw;
//! - [`subset_properties`]: far-field subsets (issue 29): even prefixes, counts against weights;
//! - [`occlusion_properties`]: occlusion culling (issue 31) against the false-cull oracle and
//!   the frame without culling; the pyramid against brute force;
//! - [`points_draw_properties`]: the point LOD's draw (issue 33): cut mode draws every placed
//!   point once, sub-pixel squares, thread-count independence.
//! - [`points_properties`]: Celba's point LOD (issue 33): area order, unions, Alg. 5 groups,
//!   opaque placement, the cut's exactly-once, batch ranges, the safe change distance;
//! - [`extremes`]: the numerical-extremes catalogue of SPEC §7.
//!
//! Run one module with `cargo test -p forestlod-tests --test properties <module>::`. proptest
//! keeps its regressions next to the source file of each property
//! (`select_properties.proptest-regressions` beside `select_properties.rs`).

mod coalesce_properties;
mod command_order_properties;
mod extremes;
mod far_properties;
mod hierarchy_properties;
mod impostor_properties;
mod occlusion_properties;
mod points_draw_properties;
mod points_properties;
mod refine_properties;
mod select_properties;
mod subset_properties;
mod tree_assembly_properties;

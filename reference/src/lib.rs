//! # forestlod-reference: the CPU oracle
//!
//! Every stage of the grouped-LOD forest pipeline of Eichner 2024 (the core seed, cited as "E§…"),
//! written to be read and trusted rather than to be fast: exact, documented, deterministic. The wgpu
//! twin in `forestlod-gpu` is judged against it. Stages share names with their WGSL twins
//! (`gpu/src/shaders/<stage>.wgsl`):
//!
//! | stage | module | seed |
//! |---|---|---|
//! | billboard bake | `bake` | E Alg. 3.1, §4.1 |
//! | alpha-aware mipmaps | [`mips`] | E Alg. 3.2, §4.1 |
//! | grid batches | [`batches`] | E§3.4, §4.2, Eq. 4.1 |
//! | per-batch selection | [`select`] | E§3.5, §4.3 |
//! | the hierarchy's cut (trees grouped by [`hierarchy`]) | [`hier_select`] | G§3 Fig. 4, C§4.5 |
//! | the cut's runs merged | [`coalesce`] | G§3 |
//! | the cut's commands front to back | [`command_order`] | E§7 |
//! | per-tree refinement of the commands | [`refine`] | E§3.5, §7 (beyond the thesis) |
//! | draw execution | `draw` | E§4.4 |
//! | the baselines' per-tree culling and Primitive quads | [`baselines`] | E§5 |
//!
//! The frame runs them in the order of `forestlod_shared::FramePlan` ([`frame`]: the selection
//! stages; [`pipeline`]: the slow path and the draw).
//!
//! Beside the pipeline, for the experiments (SPEC §9, §10): [`ground_truth`] (full meshes for every
//! tree, ray-traced with obvhs, alpha-tested, supersampled: the accuracy yardstick) and
//! [`baselines`] (E§5's *Vegetation* and *Primitive*, on the same rasterizer).
//!
//! Inputs come from [`scene`] (built-in procedural scenes and validated user scenes).
//!
//! Depends on `forestlod-shared`, glam, rayon and image/exr for I/O; never on wgpu. Parallel code
//! (rayon) only ever splits work into pieces whose results are combined in a fixed order, so the
//! output is bit-identical for any thread count.

pub mod bake;
pub mod baselines;
pub mod batches;
pub mod blend;
pub mod cameras;
pub mod coalesce;
pub mod command_order;
pub mod draw;
pub mod error;
pub mod far_bake;
pub mod files;
pub mod frame;
pub mod geometry;
pub mod ground_truth;
pub mod hier_select;
pub mod hierarchy;
pub mod hull;
pub mod impostor_cache;
pub mod metric;
pub mod mips;
pub mod occlude;
pub mod output;
pub mod pipeline;
pub mod precision;
pub mod pyramid;
pub mod raster;
pub mod refine;
pub mod sampler;
pub mod scene;
pub mod select;
pub mod subset;
pub mod texture;
// Issue 33 item 1: Celba's point LOD (CPU preprocessing and selection).
pub mod points;

pub use error::InputError;
pub use forestlod_shared as shared;

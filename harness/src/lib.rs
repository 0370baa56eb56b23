//! # forestlod-harness: run a stage or a frame on every backend and judge it
//!
//! The crate between the two twins (`forestlod-reference`, `forestlod-gpu`) and the programs that
//! compare them (the `forestlod` CLI in `experiments/`, the test suites in `tests/`). It owns:
//! - [`gpu_frame`]: the GPU frame, run in one place: `GpuScene` (one prepared scene on the GPU,
//!   any frame of ours or of a baseline, the stages of its `FramePlan` in order), `render_gpu` (one
//!   frame of ours), the selection chain and `StagesFromCpu` (which stages the reference computes
//!   instead, the CLI's `--stage-from-cpu`, by stage name);
//! - [`bridge`]: the reference-to-GPU bridge (a prepared scene's buffers, textures and trees
//!   converted to the GPU drivers' types and uploaded);
//! - [`backend`]: the GPU backends of select and draw;
//! - [`alternatives`]: the reference frames that classify threshold-ambiguous pixels;
//! - [`context`]: the process's one GPU context;
//! - [`stages`]: the stage table, every `forestlod_shared::StageId` with its twins, backend and
//!   parity case (walked by `tests/tests/parity/stage_table.rs`);
//! - [`stage`]: the one family of backend traits, `Backend<S: Stage>` for every stage, and the
//!   reference backend of every stage ("one test body, several backends", SPEC §8);
//! - [`texel_compare`]: the GPU mips and bake backends and the RGBA8 texel tally (SPEC §5.1, §5.2);
//! - [`image_compare`]: the image parity classes, every tolerance a named constant (SPEC §8);
//! - [`stage_defs`]: the stages beyond select, draw, mips and bake (`hier_select`, `coalesce`,
//!   `command_order`, `refine`, `cull`, `primitive`) and the judge of every stage
//!   ([`stage::Judged`]);
//! - [`judge`]: how the list stages' outputs are compared, the near-threshold (fused
//!   multiply-add) classification and its tolerances, shared by the parity tests and [`diagnose`];
//! - [`contraction`]: what a conforming adapter may compute for the shared selection formulas
//!   (every fused multiply-add the Vulkan specification allows), the derived bound of the
//!   front-to-back keys and the decisions reachable at a knife edge;
//! - [`gpu_stages`]: the GPU twin of each stage run alone on the reference's input of it, and
//!   `FrameStages`, every stage of one frame judged (issue 27);
//! - [`diagnose`]: each GPU stage before the draw compared with the reference's in the frame
//!   plan's order, so a failing frame names the first stage that differs (issues 15, 27);
//! - [`stats`]: statistical parity, the signed-difference histogram and bias gate of every
//!   compared buffer (issue 15).
//!
//! Rules:
//! - nothing here depends on a test framework (no proptest): the shipped CLI links this crate, and
//!   nothing shipped links `forestlod-tests`;
//! - the reference and the GPU twin meet here and in the tests only, never in each other;
//! - a GPU object shared between threads holds no per-frame state behind `&self` (the rule of
//!   `forestlod-gpu`); objects that own per-frame state here (`GpuScene`) take `&mut self`.
//!
//! Rejected design: keeping these modules in `forestlod-tests` and letting the CLI depend on it
//! (the state before issue 11) made the shipped binary link proptest and the test scaffolding.

pub mod alternatives;
pub mod backend;
pub mod bridge;
pub mod context;
pub mod contraction;
pub mod diagnose;
pub mod flip;
pub mod gpu_frame;
pub mod gpu_stages;
pub mod image_compare;
pub mod judge;
pub mod stage;
pub mod stage_defs;
pub mod stages;
pub mod stats;
pub mod texel_compare;

//! # forestlod-experiments
//!
//! The programs users run: the `forestlod` command line (scene info, selection, rendering, sweeps),
//! the criterion benchmarks and the experiment programs. Shared here: resolving a scene from the
//! command line and assembling [`forestlod_shared::Params`] from flags, each with the one-line
//! errors the brief asks for (field and value, never a panic).

pub mod camera;
pub mod case;
pub mod chart;
pub mod check;
pub mod example_data;
pub mod fair;
pub mod gpu_time;
pub mod html;
pub mod legend;
pub mod metrics;
pub mod options;
pub mod plot;
pub mod render;
pub mod report;
pub mod resident;
pub mod sweep;
pub mod temporal;

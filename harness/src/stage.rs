//! One family of backend traits for every stage and every backend ("one test body, several
//! backends", SPEC §8): a [`Stage`] names what goes in and what comes out, a [`Backend<S>`] runs
//! stage `S`. [`Reference`] (the CPU oracle) is one backend of every stage; each GPU twin is one
//! type per stage, beside the code that drives it (`GpuSelectBackend`, `GpuRenderer` in
//! [`crate::backend`], the six stages run alone in [`crate::gpu_stages`], `GpuMipsBackend`, `GpuBakeBackend` in [`crate::texel_compare`]). A test
//! written against `&dyn Backend<S>` runs on any backend of `S`; a new backend (a variant's GPU
//! twin) is one `impl Backend<S>`, a new stage one `impl Stage` (a test binary may declare its
//! own, as `tests/tests/properties/extremes.rs` does for whole frames from a scene).
//!
//! Every stage of the stage table (`crate::stages`) is a [`Stage`] here or in
//! [`crate::stage_defs`] (re-exported), with its [`Reference`] backend and its judge
//! ([`Judged`]: how another backend's output is compared with the reference's, reported as a
//! [`StageCheck`] with the largest difference seen); [`compare`] runs any two backends of a stage
//! through `&dyn Backend<S>` and judges. The GPU twins of the stages run alone are
//! [`crate::gpu_stages`].
//!
//! vello keeps one stage signature for every CPU twin (`vello_shaders/src/cpu/*.rs`); the same
//! idea here takes typed inputs and outputs because our stages' buffers differ in kind.
//!
//! Rejected design: one trait per stage (`SelectBackend`, `Renderer`, `MipsBackend`,
//! `BakeBackend`, and a fifth in the extremes tests), as before issue 11: five names, five
//! `name()` methods, and no way to write a helper over "any backend of any stage".

use forestlod_reference::pipeline::Prepared;
use forestlod_reference::scene::TreeMesh;
use forestlod_reference::select::{batch_decisions_banded, select};
use forestlod_reference::texture::Rgba8Image;
use forestlod_shared::{BatchMeta, Camera, MeshMeta, MipMode, Params, StageId};

use forestlod_reference::mips::AlphaAdjust;
use forestlod_reference::raster::RenderTarget;
use forestlod_reference::select::{Decision, Selection};

use crate::image_compare::Images;

pub use crate::stage_defs::*;

/// A stage as the harness runs it: its input and its output in the reference's terms.
pub trait Stage {
    /// What one run takes.
    type Input<'a>;
    /// What one run gives.
    type Output;
}

/// A backend's name for reports, e.g. `reference`, `gpu-stable`, `gpu(from-cpu: select)`: one
/// per backend type, whatever stages it runs.
pub trait Named {
    /// The name.
    fn name(&self) -> String;
}

/// One backend's implementation of stage `S`.
pub trait Backend<S: Stage>: Named {
    /// Whether outputs come in the reference's order (else a test compares them as a multiset).
    fn ordered(&self) -> bool {
        true
    }
    /// Runs the stage once. Inputs are valid (validated parameters, a prepared scene); a backend
    /// that fails anyway panics naming itself: the harness serves tests and the CLI's parity run,
    /// which report the panic as the failure.
    fn run(&self, input: S::Input<'_>) -> S::Output;
}

/// One stage's comparison: a backend's output against the reference's, as a [`Judged`] stage's
/// judge or the diagnosis reports it.
#[derive(Clone, Debug)]
pub struct StageCheck {
    /// The stage, e.g. `coalesce` or `billboards (bake + mips)`.
    pub stage: &'static str,
    /// What was compared and found, the largest difference included.
    pub summary: String,
    /// The largest difference seen, in the stage's own unit (named in `summary`).
    pub max_difference: f64,
    /// Whether the stage's output differs beyond what a correct build shows.
    pub differs: bool,
}

impl StageCheck {
    /// The check of `stage` from a judge's result: `Ok((summary, max difference))` passes,
    /// `Err(why)` differs.
    pub fn of(stage: StageId, result: Result<(String, f64), String>) -> Self {
        match result {
            Ok((summary, max_difference)) => Self {
                stage: stage.name(),
                summary,
                max_difference,
                differs: false,
            },
            Err(why) => Self {
                stage: stage.name(),
                summary: why,
                max_difference: f64::INFINITY,
                differs: true,
            },
        }
    }
}

/// A stage with a judge (issue 27): how another backend's output is compared with the
/// reference's, with the tolerances the stage allows (named constants, [`crate::judge`]). The
/// parity tests and the diagnosis share it.
pub trait Judged: Stage {
    /// Judges `other`'s output against `reference`'s for the same `input`.
    fn judge(input: Self::Input<'_>, reference: &Self::Output, other: &Self::Output) -> StageCheck;
}

/// Runs `input` through `reference` and `other` (any two backends of `S`) and judges `other`'s
/// output: "one test body, several backends".
pub fn compare<'a, S: Judged>(
    reference: &dyn Backend<S>,
    other: &dyn Backend<S>,
    input: S::Input<'a>,
) -> StageCheck
where
    S::Input<'a>: Copy,
{
    let want = reference.run(input);
    let got = other.run(input);
    S::judge(input, &want, &got)
}

/// The CPU oracle: a backend of every stage.
#[derive(Clone, Copy, Debug, Default)]
pub struct Reference;

impl Named for Reference {
    fn name(&self) -> String {
        "reference".into()
    }
}

/// `select` (E§3.5, SPEC §6): the batches of a frame, their commands and per-batch decisions.
pub struct Select;

/// The input of [`Select`].
#[derive(Clone, Copy)]
pub struct SelectInput<'a> {
    /// Batch records.
    pub batches: &'a [BatchMeta],
    /// Each batch's tree scale range (issue 29's group band).
    pub scales: &'a [[f32; 2]],
    /// Mesh records.
    pub meshes: &'a [MeshMeta],
    /// The billboard quad's record.
    pub billboard: &'a MeshMeta,
    /// The camera (valid).
    pub camera: &'a Camera,
    /// Parameters (valid).
    pub params: &'a Params,
}

impl Stage for Select {
    type Input<'a> = SelectInput<'a>;
    type Output = BackendSelection;
}

impl Backend<Select> for Reference {
    fn run(&self, i: SelectInput<'_>) -> BackendSelection {
        BackendSelection {
            selection: select(
                i.batches,
                i.scales,
                i.meshes,
                i.billboard,
                i.camera,
                i.params,
            ),
            decisions: batch_decisions_banded(i.batches, i.scales, i.meshes, i.camera, i.params),
        }
    }
}

/// `draw` (SPEC §5.5): one frame of a prepared scene, selection and refine included.
pub struct Draw;

/// The input of [`Draw`].
#[derive(Clone, Copy)]
pub struct FrameInput<'a> {
    /// The scene, prepared with `params`.
    pub prepared: &'a Prepared,
    /// The camera (valid).
    pub camera: &'a Camera,
    /// Parameters (valid), those `prepared` was prepared with.
    pub params: &'a Params,
}

impl Stage for Draw {
    type Input<'a> = FrameInput<'a>;
    type Output = Images;
}

impl Backend<Draw> for Reference {
    fn run(&self, i: FrameInput<'_>) -> Images {
        let frame = i
            .prepared
            .render(i.camera, i.params)
            .expect("reference render");
        images_of(&frame.drawn.target)
    }
}

/// `mips` (E Alg. 3.2, SPEC §5.2): level-0 layers in, every level of every layer out,
/// `[layer][level]`.
pub struct Mips;

/// The input of [`Mips`].
#[derive(Clone, Copy)]
pub struct MipsInput<'a> {
    /// Level-0 layers, equal square power-of-two sizes.
    pub layers: &'a [Rgba8Image],
    /// The mip mode.
    pub mode: MipMode,
    /// The alpha-test reference the coverage is kept for.
    pub alpha_ref: f32,
}

impl Stage for Mips {
    type Input<'a> = MipsInput<'a>;
    type Output = Vec<Vec<LevelOut>>;
}

/// `bake` (E Alg. 3.1, SPEC §5.1): level 0 of every billboard layer `mesh * K + k`
/// (`mesh·K·J + k·J + j` with `J` azimuth views, issue 30).
pub struct Bake;

/// The input of [`Bake`].
#[derive(Clone, Copy)]
pub struct BakeInput<'a> {
    /// The species meshes.
    pub meshes: &'a [TreeMesh],
    /// K, the baked elevation angles.
    pub angle_count: u32,
    /// J, the baked azimuth views per angle (issue 30; 1 is the thesis).
    pub azimuth_count: u32,
    /// `ViewSphere` as `u32` (issue 32): elevation views, or `N×N` octahedral frames.
    pub sphere: u32,
    /// The octahedral grid side `N` (issue 32; read only under octahedral views).
    pub grid: u32,
    /// The layer side, texels.
    pub side: u32,
    /// Whether the octahedral impostors' depth channel is baked too (issue 32,
    /// `forestlod_shared::depth_channel`): its layers then follow the colour layers, in the same
    /// order.
    pub depth: bool,
}

impl Stage for Bake {
    type Input<'a> = BakeInput<'a>;
    type Output = Vec<Rgba8Image>;
}

/// What a backend's selection produced: the output buffers and the per-batch decisions.
#[derive(Clone, Debug, PartialEq)]
pub struct BackendSelection {
    /// Commands, data and counters, as the reference's [`Selection`].
    pub selection: Selection,
    /// The decision of each batch, in batch order.
    pub decisions: Vec<Decision>,
}

/// The buffers of a reference [`RenderTarget`] as [`Images`].
pub fn images_of(target: &RenderTarget) -> Images {
    Images {
        width: target.width(),
        height: target.height(),
        color: target.color().to_vec(),
        depth: target.depth().to_vec(),
        lod_id: target.aux().to_vec(),
    }
}

/// One level of one layer as a mips backend reports it, in the reference's terms.
#[derive(Clone, Debug, PartialEq)]
pub struct LevelOut {
    /// The final texels.
    pub image: Rgba8Image,
    /// `[MinAlpha_k, MaxAlpha_k]` of the raw level.
    pub raw_alpha_range: [f32; 2],
    /// How raw alpha became final alpha.
    pub adjust: AlphaAdjust,
    /// Texels passing the alpha test.
    pub pass_count: u64,
}

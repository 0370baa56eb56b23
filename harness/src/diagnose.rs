//! Which stage differs first (issue 15, "a failure names the first stage whose output differs";
//! issue 27, every stage): a frame drawn by the GPU from its own textures and selection passes
//! through the stages of its plan ([`FramePlan::stages`]: bake, mips, the selection stages, then
//! draw). When the image comparison is the only check, a wrong bake shows up as an image failure
//! blamed on "colour"; this module compares each stage's output with the reference's, in the
//! plan's order, **before** the images, so a test can name the stage.
//!
//! Per stage:
//! - **textures** (mesh mips; billboard bake + mips): every level of every layer read back and
//!   compared texel by texel; the stage differs when more than [`STAGE_TEXEL_MAX_FRACTION`] of
//!   its texels are beyond ±1 per channel, or when its texels are biased
//!   ([`crate::texel_compare::TexelTally::bias_failures`] at [`BAKE_BIAS_MAX`]);
//! - **each selection stage** (`select`, or `hier_select`, `coalesce`, `command_order`; then
//!   `refine`): run alone on the GPU on the reference's input of it
//!   ([`crate::gpu_stages::FrameStages::check`]) and judged by the stage's judge
//!   ([`crate::stage::Judged`], tolerances in [`crate::judge`]), so the first wrong stage is
//!   named even when later ones are right;
//! - **the chained selection**: the GPU's own selection stages one after the other (stable
//!   compaction) against the reference's commands and per-command data, exactly.

use forestlod_gpu::{Compaction, GpuContext, MipArray};
use forestlod_reference::pipeline::Prepared;
use forestlod_reference::sampler::Texture;
use forestlod_shared::{Camera, FramePlan, Params, StageId};

use crate::bridge::gpu_textures;
use crate::gpu_frame::SelectionChain;
use crate::gpu_stages::FrameStages;
pub use crate::stage::StageCheck;
use crate::texel_compare::TexelTally;

/// Fraction of a texture stage's texels that may differ by more than ±1 per channel before the
/// stage counts as differing.
///
/// Why 6e-3: `parity::bake` classifies the texels a correct bake may get wrong by more than 1
/// (discard-ambiguous and filter-window texels, up to 255 apart, which the mips then spread over
/// the coarser levels): measured over every level 5.6e-4 of the texels at r = 64 and 2.05e-3 at
/// r = 32 (`parity::draw`, lavapipe); 6e-3 keeps a factor 3 over the worst. A wrong layer, angle
/// or mip rule changes most covered texels (~30 % of all).
pub const STAGE_TEXEL_MAX_FRACTION: f64 = 6e-3;

/// Largest bias per reference value ([`crate::stats::SignedHistogram::value_bias_failure`]) of
/// a texture stage rendered by the GPU's rasterizer (the bake).
///
/// Why 0.5, ten times `parity::bake`'s [`crate::texel_compare::TEXEL_BIAS_MAX`]: the billboards
/// here are small (r = 32 in `parity::draw`'s `tiny` scenarios) and every mip level is compared,
/// so a lean of lavapipe's bake propagates through the chain: measured +0.16 per value in green
/// (108 values up, 30 down) at r = 32, K = 8 on a correct build (at r = 128 the same bake
/// balances to 0.015). 0.5 keeps a factor 3; a bake or mip rule that moves every colour a step
/// the same way (bias 1) still exceeds it.
pub const BAKE_BIAS_MAX: f64 = 0.5;

/// A texture stage's check from its texel tally: differs when more than
/// [`STAGE_TEXEL_MAX_FRACTION`] of its texels are beyond ±1 or when they are biased
/// ([`BAKE_BIAS_MAX`]); the maximum difference is the largest channel difference.
pub fn texel_check(stage: &'static str, tally: &TexelTally) -> StageCheck {
    let fraction = tally.over_tolerance as f64 / tally.texels.max(1) as f64;
    let bias = tally.bias_failures(stage, BAKE_BIAS_MAX);
    StageCheck {
        stage,
        summary: format!(
            "{} texels, {} beyond ±1 ({fraction:.2e}, at most {STAGE_TEXEL_MAX_FRACTION}), max \
             difference {}{}",
            tally.texels,
            tally.over_tolerance,
            tally.max_diff,
            if bias.is_empty() {
                String::new()
            } else {
                format!("; {}", bias.join("; "))
            }
        ),
        max_difference: f64::from(tally.max_diff),
        differs: fraction > STAGE_TEXEL_MAX_FRACTION || !bias.is_empty(),
    }
}

/// Compares the GPU's textures (mesh mips, billboards) with the reference's.
pub fn check_textures(ctx: &GpuContext, prepared: &Prepared, params: &Params) -> Vec<StageCheck> {
    let textures = gpu_textures(ctx, prepared, params).expect("GPU textures");
    let mode = params.mips().expect("valid mip mode");
    let read = |t: wgpu::Texture| {
        MipArray::from_texture(ctx, t, mode, params.alpha_cutoff)
            .expect("wrap texture")
            .read_chains(ctx)
            .expect("read chains")
    };
    let mut out = Vec::new();
    let mut tally = TexelTally::default();
    for (layer, chain) in read(textures.mesh).iter().enumerate() {
        let t = &prepared.mesh_textures[layer];
        for (k, level) in chain.iter().enumerate() {
            tally.compare(
                &format!("mesh {layer} level {k}"),
                &level.texels,
                &t.level(0, k).texels,
                1,
            );
        }
    }
    out.push(texel_check("mesh textures (mips)", &tally));
    let compare_array = |name: &str, got: wgpu::Texture, reference: &Texture| {
        let mut tally = TexelTally::default();
        for (layer, chain) in read(got).iter().enumerate() {
            for (k, level) in chain.iter().enumerate() {
                tally.compare(
                    &format!("{name} layer {layer} level {k}"),
                    &level.texels,
                    &reference.level(layer as u32, k).texels,
                    1,
                );
            }
        }
        tally
    };
    let tally = compare_array(
        "billboard",
        textures.billboards,
        &prepared.billboards.texture,
    );
    out.push(texel_check("billboards (bake + mips)", &tally));
    // The octahedral impostors' depth channel (issue 32), when both sides baked it.
    match (textures.depth, &prepared.billboards.depth) {
        (Some(got), Some(want)) => {
            let tally = compare_array("depth", got, &want.texture);
            out.push(texel_check("billboard depth (bake + mips)", &tally));
        }
        (None, None) => {}
        (got, want) => out.push(StageCheck {
            stage: "billboard depth (bake + mips)",
            summary: format!(
                "the GPU baked {} depth channel, the reference {}",
                if got.is_some() { "a" } else { "no" },
                if want.is_some() { "one" } else { "none" }
            ),
            max_difference: f64::INFINITY,
            differs: true,
        }),
    }
    out
}

/// Compares the GPU's selection stages before `refine` (`select.wgsl` with the stable
/// compaction, or the cut: `hier_select.wgsl`, `coalesce.wgsl`, `command_order.wgsl`, as the
/// frame's plan says) with the reference's ([`Prepared::select`]), exactly.
pub fn check_select(
    ctx: &'static GpuContext,
    prepared: &Prepared,
    camera: &Camera,
    params: &Params,
) -> StageCheck {
    // Under hierarchical impostors (issue 33 item 2) both read the frame's impostor state (a
    // path's first frame, as `Prepared::render`).
    let impostors = prepared
        .first_impostor_frame(camera, params)
        .expect("valid parameters")
        .map(|(c, _)| c);
    let far = impostors.as_ref().map(|c| c.level());
    let before_refine = Params {
        tree_cull: forestlod_shared::TreeCull::None as u32,
        ..*params
    };
    let want = prepared
        .select_stages_on(far, camera, &before_refine, false)
        .selection;
    let mut gpu = SelectionChain::gpu(ctx, prepared).expect("GPU selection");
    if let Some(far) = far {
        gpu.write_far_nodes(&far.nodes)
            .expect("the frame's far node records");
    }
    let got = gpu
        .dispatch(camera, params, Compaction::Stable)
        .and_then(|b| b.read(ctx))
        .expect("GPU selection readback");
    let n = want.commands.len().max(got.commands.len());
    let differing = (0..n)
        .filter(|&i| {
            want.commands.get(i) != got.commands.get(i) || want.data.get(i) != got.data.get(i)
        })
        .count();
    StageCheck {
        stage: if prepared.hierarchy.is_some() {
            "hier_select + coalesce + command_order"
        } else {
            "select"
        },
        summary: format!(
            "{} reference commands, {} GPU commands, {differing} differing",
            want.commands.len(),
            got.commands.len()
        ),
        max_difference: differing as f64,
        differs: differing > 0,
    }
}

/// The selection stages of the frame's plan ([`FramePlan::selection_stages`]), each run alone on
/// the GPU on the reference's input of it ([`FrameStages::check`]) and judged, in plan order.
pub fn check_selection_stages(
    ctx: &'static GpuContext,
    prepared: &Prepared,
    camera: &Camera,
    params: &Params,
) -> Vec<StageCheck> {
    let plan = FramePlan::new(params).expect("valid parameters");
    let frame = FrameStages::new(prepared, camera, params);
    plan.selection_stages()
        .into_iter()
        .filter_map(|s| frame.check(ctx, s))
        .collect()
}

/// The stages the GPU ran before its draw, compared in the plan's order
/// ([`FramePlan::stages`]): the textures (bake, then mips) unless `textures_from_cpu`; unless
/// `select_from_cpu`, each selection stage alone on the reference's input
/// ([`check_selection_stages`]), then the GPU's chained selection ([`check_select`]: a stage
/// that is right alone but wired to the wrong buffer shows there). The draw is judged by the
/// image comparison that follows.
pub fn check_stages(
    ctx: &'static GpuContext,
    prepared: &Prepared,
    camera: &Camera,
    params: &Params,
    textures_from_cpu: bool,
    select_from_cpu: bool,
) -> Vec<StageCheck> {
    let plan = FramePlan::new(params).expect("valid parameters");
    let mut out = Vec::new();
    let mut selection_done = false;
    for stage in plan.stages() {
        match stage {
            StageId::Bake if !textures_from_cpu => {
                out.extend(check_textures(ctx, prepared, params))
            }
            s if plan.selection_stages().contains(&s) && !select_from_cpu && !selection_done => {
                selection_done = true;
                out.extend(check_selection_stages(ctx, prepared, camera, params));
                out.push(check_select(ctx, prepared, camera, params));
            }
            _ => {}
        }
    }
    out
}

/// The first stage of `checks` that differs, as a failure line, else `None`.
pub fn first_differing(checks: &[StageCheck]) -> Option<String> {
    checks.iter().find(|c| c.differs).map(|c| {
        format!(
            "first differing stage: {} ({}); the image comparison below it is a consequence",
            c.stage, c.summary
        )
    })
}

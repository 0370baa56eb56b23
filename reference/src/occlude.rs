//! Occlusion culling of the selected commands (issue 31): the reference twin of
//! `gpu/src/shaders/occlude.wgsl`, shader-shaped like [`crate::refine`]: one command is one
//! workgroup, each writing only its own ranges. The frame, the formulas and why the test is
//! conservative are in `forestlod_shared::occlusion`; [`crate::pipeline::Prepared::render`] runs
//! the two passes around [`crate::pyramid::Pyramid`].
//!
//! ## Contract
//! Input: the frame's [`Selection`] (after every selection stage, `refine` included) over its
//! indirection of `m` entries, every tree's footprint sphere (`Prepared::footprints`: the base and
//! [`crate::draw::tree_footprint_radius`]), the camera, valid parameters, and per tree whether it
//! passed the previous frame's test (`visible_before`, empty for none: a path's first frame).
//! - [`occlude_early`] writes, per command, its trees that are occluders
//!   ([`forestlod_shared::is_occluder`]), **in list order**, at
//!   [`forestlod_shared::occlusion_slot`]`(0, lod, m, first_instance)` of a `4m` indirection, and
//!   returns the early selection: the same commands, `first_instance` at the slot,
//!   `instance_count` the kept count.
//! - [`occlude_late`] tests the command's trees against the pyramid (under `single` the early
//!   ones are not tested: they pass) and writes the trees that pass, **in list order**, at slot
//!   `(1, lod, m, first_instance)`: the final pass's lists (early trees included under `exact`,
//!   left out under `reorder`, [`forestlod_shared::OcclusionOrder`]); it returns the
//!   final selection, the counters, and per tree whether it passed (the next frame's
//!   `visible_before`; a tree of two commands passes when either passes).
//!
//! Commands are never removed, reordered or given new data: the draw stage needs no change.
//!
//! ## Invariants (tests in `tests/tests/properties/occlusion_properties.rs`)
//! - **No false cull**: every tree with a fragment in the frame without occlusion culling is in
//!   the early or the late selection.
//! - **Bit-identical frames** in the dithered fade modes, but for counted depth ties.
//! - **Deterministic** for any thread count.

use forestlod_shared::{
    Camera, Occlusion, OcclusionBound, OcclusionCounters, Params, coverage, effective_mode,
    final_includes_early, is_occluder, may_occlude, nearest_occluder_depth, occluded,
    occlusion_bounds, occlusion_slot, view_interval,
};
use rayon::prelude::*;

use crate::pyramid::Pyramid;
use crate::select::Selection;

/// A tree's footprint sphere: its base point and a radius containing every vertex the draw can
/// give it ([`crate::draw::tree_footprint_radius`]).
pub type Footprint = ([f32; 3], f32);

/// What the early rule reads besides the tree (module docs): the camera's projection, the
/// [`forestlod_shared::effective_mode`] and `single`'s [`nearest_occluder_depth`].
struct EarlyRule<'a> {
    mode: u32,
    nearest: f32,
    params: &'a Params,
    camera: &'a Camera,
    view_proj: glam::Mat4,
    forward: [f32; 3],
    visible_before: &'a [u32],
}

impl<'a> EarlyRule<'a> {
    fn new(
        selection: &Selection,
        indirection: &[u32],
        footprints: &[Footprint],
        camera: &'a Camera,
        params: &'a Params,
        visible_before: &'a [u32],
    ) -> Self {
        let mut rule = EarlyRule {
            mode: effective_mode(params.occlusion, !visible_before.is_empty()),
            nearest: 0.0,
            params,
            camera,
            view_proj: camera.view_projection(),
            forward: camera.basis().forward.to_array(),
            visible_before,
        };
        if rule.mode == Occlusion::Single as u32 {
            // The min-reduction over the in-view mesh trees that may occlude.
            rule.nearest = nearest_occluder_depth(
                selection
                    .commands
                    .par_iter()
                    .zip(&selection.data)
                    .filter(|(_, d)| {
                        d.lod == forestlod_shared::LOD_MESH
                            && may_occlude(d, params.fade_mode, params.subset_mode)
                    })
                    .flat_map_iter(|(cmd, _)| {
                        let off = cmd.first_instance as usize;
                        indirection[off..off + cmd.instance_count as usize].iter()
                    })
                    .filter_map(|&t| {
                        let (near, bound) = rule.depth_and_bound(footprints[t as usize]);
                        (!matches!(bound, OcclusionBound::Offscreen)).then_some(near)
                    })
                    .collect::<Vec<f32>>(),
            );
        }
        rule
    }

    /// A footprint's nearest view depth and its bound.
    fn depth_and_bound(&self, (base, radius): Footprint) -> (f32, OcclusionBound) {
        let c = self.camera;
        let near = view_interval(base, radius, c.eye, self.forward).lo;
        let bound = occlusion_bounds(&self.view_proj, c.near, base, radius, c.width, c.height);
        (near, bound)
    }

    /// Whether tree `tree` of a command with data `data` is an occluder
    /// ([`forestlod_shared::is_occluder`], read the same way by both phases), with its bound.
    fn early(
        &self,
        data: &forestlod_shared::CommandData,
        footprint: Footprint,
        tree: u32,
    ) -> (bool, OcclusionBound) {
        let (near, bound) = self.depth_and_bound(footprint);
        let before = self
            .visible_before
            .get(tree as usize)
            .is_some_and(|&v| v != 0);
        let early = is_occluder(
            self.mode,
            data,
            self.params,
            near - self.nearest,
            before,
            &bound,
        );
        (early, bound)
    }
}

/// The early selection and the `4m` indirection with its early ranges written (module docs).
pub fn occlude_early(
    selection: &Selection,
    indirection: &[u32],
    footprints: &[Footprint],
    camera: &Camera,
    params: &Params,
    visible_before: &[u32],
) -> (Selection, Vec<u32>) {
    let m = indirection.len() as u32;
    let rule = EarlyRule::new(
        selection,
        indirection,
        footprints,
        camera,
        params,
        visible_before,
    );
    let lists: Vec<Vec<u32>> = selection
        .commands
        .par_iter()
        .zip(&selection.data)
        .map(|(cmd, data)| {
            let off = cmd.first_instance as usize;
            indirection[off..off + cmd.instance_count as usize]
                .iter()
                .copied()
                .filter(|&t| {
                    let (e, _) = rule.early(data, footprints[t as usize], t);
                    coverage::hit(coverage::Threshold::OccludeEarly, e);
                    e
                })
                .collect()
        })
        .collect();
    let mut out = vec![0u32; 4 * m as usize];
    let mut early = selection.clone();
    for ((cmd, data), list) in early.commands.iter_mut().zip(&selection.data).zip(lists) {
        let slot = occlusion_slot(0, data.lod, m, cmd.first_instance);
        out[slot as usize..slot as usize + list.len()].copy_from_slice(&list);
        cmd.first_instance = slot;
        cmd.instance_count = list.len() as u32;
    }
    (early, out)
}

/// What the late test produced (module docs).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LateTest {
    /// The late selection over the `4m` indirection.
    pub selection: Selection,
    /// The stage's counters (`early` included).
    pub counters: OcclusionCounters,
    /// Per tree, 1 when it passed the test this frame (early trees under `single` count as
    /// passed): the next frame's `visible_before`.
    pub visible: Vec<u32>,
}

/// The late test and the late selection (module docs); writes the late ranges of `out`, the
/// `4m` indirection [`occlude_early`] returned. `trees` is the scene's tree count.
#[allow(clippy::too_many_arguments)]
pub fn occlude_late(
    selection: &Selection,
    indirection: &[u32],
    footprints: &[Footprint],
    camera: &Camera,
    params: &Params,
    visible_before: &[u32],
    pyramid: &Pyramid,
    out: &mut [u32],
) -> LateTest {
    let m = indirection.len() as u32;
    assert_eq!(out.len(), 4 * m as usize, "the 4m indirection");
    let rule = EarlyRule::new(
        selection,
        indirection,
        footprints,
        camera,
        params,
        visible_before,
    );
    let mode = rule.mode;
    let with_early = final_includes_early(params.occlusion_order);
    // One workgroup per command: (late list, passed trees, counters).
    let per_command: Vec<(Vec<u32>, Vec<u32>, OcclusionCounters)> = selection
        .commands
        .par_iter()
        .zip(&selection.data)
        .map(|(cmd, data)| {
            let off = cmd.first_instance as usize;
            let mut c = OcclusionCounters::default();
            let (mut late, mut passed) = (Vec::new(), Vec::new());
            for &t in &indirection[off..off + cmd.instance_count as usize] {
                let fp = footprints[t as usize];
                let (early, bound) = rule.early(data, fp, t);
                c.early += early as u32;
                if early && mode == Occlusion::Single as u32 {
                    passed.push(t);
                    if with_early {
                        late.push(t);
                    }
                    continue;
                }
                c.tested += 1;
                let pass = match bound {
                    OcclusionBound::Unbounded => {
                        c.unbounded += 1;
                        true
                    }
                    OcclusionBound::Offscreen => {
                        c.offscreen += 1;
                        false
                    }
                    OcclusionBound::Rect(r) => {
                        let hidden = occluded(&r, pyramid.max_under(&r));
                        c.occluded += hidden as u32;
                        !hidden
                    }
                };
                coverage::hit(coverage::Threshold::OccludeLate, pass);
                if pass {
                    passed.push(t);
                    if with_early || !early {
                        late.push(t);
                    }
                }
            }
            c.late = late.len() as u32;
            (late, passed, c)
        })
        .collect();
    let mut counters = OcclusionCounters::default();
    let mut visible = vec![0u32; footprints.len()];
    let mut late_sel = selection.clone();
    for ((cmd, data), (late, passed, c)) in late_sel
        .commands
        .iter_mut()
        .zip(&selection.data)
        .zip(per_command)
    {
        let slot = occlusion_slot(1, data.lod, m, cmd.first_instance);
        out[slot as usize..slot as usize + late.len()].copy_from_slice(&late);
        cmd.first_instance = slot;
        cmd.instance_count = late.len() as u32;
        for t in passed {
            visible[t as usize] = 1;
        }
        counters.early += c.early;
        counters.tested += c.tested;
        counters.occluded += c.occluded;
        counters.offscreen += c.offscreen;
        counters.late += c.late;
        counters.unbounded += c.unbounded;
    }
    LateTest {
        selection: late_sel,
        counters,
        visible,
    }
}

/// The trees of `selection` that neither pass of a frame drew for good (`early` under
/// `reorder`, and `late`, over `occ_indirection`; `exact`'s final lists hold its early trees): a
/// selection of the same commands over a `2m` indirection at `lod·m + first_instance`. The
/// zero-false-cull oracle draws them alone ([`crate::pipeline::Prepared::false_cull_pixels`]).
pub fn culled_selection(
    selection: &Selection,
    indirection: &[u32],
    (early, late): (&Selection, &Selection),
    occ_indirection: &[u32],
    order: u32,
) -> (Selection, Vec<u32>) {
    let m = indirection.len() as u32;
    let mut out = vec![0u32; 2 * m as usize];
    let mut culled = selection.clone();
    let list = |c: &forestlod_shared::DrawCommand| {
        &occ_indirection[c.first_instance as usize..(c.first_instance + c.instance_count) as usize]
    };
    for (i, cmd) in culled.commands.iter_mut().enumerate() {
        let off = cmd.first_instance as usize;
        let all = &indirection[off..off + cmd.instance_count as usize];
        let mut drawn: Vec<u32> = list(&late.commands[i]).to_vec();
        if !final_includes_early(order) {
            drawn.extend_from_slice(list(&early.commands[i]));
        }
        drawn.sort_unstable();
        let slot = (selection.data[i].lod.min(1) * m + cmd.first_instance) as usize;
        let mut n = 0usize;
        for &t in all {
            if drawn.binary_search(&t).is_err() {
                out[slot + n] = t;
                n += 1;
            }
        }
        cmd.first_instance = slot as u32;
        cmd.instance_count = n as u32;
    }
    (culled, out)
}

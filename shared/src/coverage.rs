//! Threshold coverage (issue 15, part 4): which side of each decision threshold of `select`,
//! `refine`, the per-tree cull (`cull.wgsl`'s oracle), the hierarchy's cut and `draw` a run of the
//! reference reached. Test-only: the counters exist only with the `coverage` feature (enabled by
//! `forestlod-tests`, never by a shipped binary's own build), and even then record only between
//! [`enable`] and [`disable`]. Without the feature [`hit`] is an empty inline function and
//! [`enabled`] the constant `false`, so the reference stages compile to what they were.
//!
//! Each [`Threshold`] has two sides (`false`: the first label of [`Threshold::sides`], `true`: the
//! second). A threshold is *straddled* by a case when the case reaches both sides; the test
//! `coverage` (`tests/tests/coverage.rs`) requires every threshold to be straddled by at least one
//! parity scenario or property case and prints the table of which case reaches which side.

/// A decision threshold of a reference stage, with two sides.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[repr(u8)]
pub enum Threshold {
    /// `select`: a batch's interval starts within / beyond the draw distance.
    SelectDrawDistance,
    /// `select`: a batch (within the draw distance) is inside / outside the frustum.
    SelectFrustum,
    /// `select`: a batch (within the draw distance) is inside / outside the left plane.
    SelectPlaneLeft,
    /// `select`: the same, right plane.
    SelectPlaneRight,
    /// `select`: the same, bottom plane.
    SelectPlaneBottom,
    /// `select`: the same, top plane.
    SelectPlaneTop,
    /// `select`: the same, near plane.
    SelectPlaneNear,
    /// `select`: the same, far plane.
    SelectPlaneFar,
    /// `select`: a drawn batch's interval starts at or past / before the fade band's end (LOD0).
    SelectFadeEnd,
    /// `select`: a drawn batch's interval ends before / at or past the fade band's start (LOD1).
    SelectFadeStart,
    /// `refine`: a tree of a refined command is needed in that LOD (decided alone) or not.
    RefineNeeded,
    /// `refine`: a needed tree's centre is within / beyond the draw distance (kept or dropped).
    RefineDrawDistance,
    /// Per-tree cull: a tree's interval starts within / beyond the draw distance.
    CullDrawDistance,
    /// Per-tree cull: a tree (within the draw distance) is inside / outside the frustum.
    CullFrustum,
    /// Per-tree cull: a drawn tree's interval starts at or past / before the fade end (LOD0).
    CullFadeEnd,
    /// Per-tree cull: a drawn tree's interval ends before / at or past the fade start (LOD1).
    CullFadeStart,
    /// Hierarchy cut: a node is not visited / visited (every ancestor recursed).
    CutVisited,
    /// Hierarchy cut: a drawn interior node is drawn as one unit / hands over to its children.
    CutRecurse,
    /// Hierarchy cut (every mode but `grid`), a node within the draw distance that one of its two
    /// frustum tests culls: culled by the sphere test alone / by the box test alone (issue 36:
    /// a mode that dropped either test is seen only on the side where that test alone culls).
    CutCullSphereVsBox,
    /// Octree cut (`octree`, `octree-euclidean`), a drawn interior node whose partial-visibility
    /// test decides: above / at or past `max_cull_depth` (the test is not made there).
    CutCullDepth,
    /// Octree cut, the partial-visibility test made: the node's box lies inside every plane /
    /// straddles one (partially visible, recurse).
    CutPartial,
    /// Octree cut, the partial-visibility test made: the box test on the node's box centre and the
    /// same test on its sphere centre agree / differ (issue 36, class 5: a test that used the wrong
    /// centre changes a decision only on this row's second side).
    CutPartialCentre,
    /// `octree-euclidean` cut with two LOD levels, a drawn interior node: its box's Euclidean
    /// distance (G§3 `dist_to`) is under the fade end (recurse) / at or past it.
    CutEuclidean,
    /// `draw`, vertex stage: a tree's centre is within / beyond the draw distance (discarded).
    DrawTreeDistance,
    /// The same for a tree of a **mesh** (LOD0) command: beyond is reached only where no per-tree
    /// refinement ran before the draw (`tree_cull = none`; `lod0` and `all` refine meshes), so the
    /// draw stage's own distance test is the only thing removing the tree (issue 36, class 4).
    DrawMeshTreeDistance,
    /// `draw`: a tree texel's alpha is at or above / below the alpha cutoff (discarded).
    DrawAlphaCutoff,
    /// `draw`: a fading fragment's depth is before / at or past the fade band's start.
    DrawFadeStart,
    /// `draw`: a fading fragment's depth is before / at or past the fade band's end.
    DrawFadeEnd,
    /// `draw`: a fading fragment's weight in a dithered mode is 0 (discarded) / 1.
    DrawDither,
    /// `draw`: a drawn fading fragment writes a LOD id other than / the transition id.
    DrawTransitionId,
    /// `select`: a drawn batch's commands draw all its trees / a far-field subset (issue 29).
    SelectSubset,
    /// `draw`, vertex stage: a tree in its command has a subset weight above 0 / of 0 (dropped).
    DrawSubsetDrop,
    /// `draw`, vertex stage: a kept tree's subset weight is whole / fading (a screen door).
    DrawSubsetFade,
    /// `draw`, `fade_granularity = tree` (issue 30, G§4): a fading fragment's tree progress is at
    /// an end of the band (0 or 1) / strictly inside it.
    DrawTreeProgress,
    /// `draw`, `dither_space = texture` (issue 30, G§4): a dithered fading fragment's noise level
    /// is 0 (the finest) / coarser.
    DrawNoiseLevel,
    /// `draw`, vertex stage, a billboard with azimuth views (issue 30): the eye's azimuth lies
    /// nearer the lower / the upper of the two views around it (the nearest view rounds down / up;
    /// a rule that truncated would be seen only on the second side).
    DrawAzimuthRound,
    /// Occlusion (issue 31): a tree of the frame is not / is an occluder, drawn in the early pass.
    OccludeEarly,
    /// Occlusion: a tested tree is culled (behind the pyramid or off screen) / passes.
    OccludeLate,
    /// `draw`, vertex stage, an octahedral impostor (issue 32): the eye lies in its cell's lower /
    /// upper triangle (a rule that read one triangle's frames only would be seen on the second).
    DrawOctahedralTriangle,
    /// The cut with a far level (issue 32): a drawn node that needs no mesh stays / goes far
    /// ([`crate::far_code`]).
    CutFar,
    /// `draw`, a far primitive's fragment (issue 32): its alpha is at or below / above the
    /// pixel's dither threshold (discarded / kept).
    DrawFarAlpha,
}

/// Every threshold, in table order.
pub const ALL: [Threshold; 41] = {
    use Threshold::*;
    [
        SelectDrawDistance,
        SelectFrustum,
        SelectPlaneLeft,
        SelectPlaneRight,
        SelectPlaneBottom,
        SelectPlaneTop,
        SelectPlaneNear,
        SelectPlaneFar,
        SelectFadeEnd,
        SelectFadeStart,
        RefineNeeded,
        RefineDrawDistance,
        CullDrawDistance,
        CullFrustum,
        CullFadeEnd,
        CullFadeStart,
        CutVisited,
        CutRecurse,
        CutCullSphereVsBox,
        CutCullDepth,
        CutPartial,
        CutPartialCentre,
        CutEuclidean,
        DrawTreeDistance,
        DrawMeshTreeDistance,
        DrawAlphaCutoff,
        DrawFadeStart,
        DrawFadeEnd,
        DrawDither,
        DrawTransitionId,
        SelectSubset,
        DrawSubsetDrop,
        DrawSubsetFade,
        DrawTreeProgress,
        DrawNoiseLevel,
        DrawAzimuthRound,
        OccludeEarly,
        OccludeLate,
        DrawOctahedralTriangle,
        CutFar,
        DrawFarAlpha,
    ]
};

impl Threshold {
    /// The threshold's name and its two sides' names (`false`, `true`).
    pub fn sides(self) -> (&'static str, &'static str, &'static str) {
        use Threshold::*;
        match self {
            SelectDrawDistance => ("select: batch vs draw distance", "within", "beyond"),
            SelectFrustum => ("select: batch vs frustum", "inside", "outside"),
            SelectPlaneLeft => ("select: batch vs left plane", "inside", "outside"),
            SelectPlaneRight => ("select: batch vs right plane", "inside", "outside"),
            SelectPlaneBottom => ("select: batch vs bottom plane", "inside", "outside"),
            SelectPlaneTop => ("select: batch vs top plane", "inside", "outside"),
            SelectPlaneNear => ("select: batch vs near plane", "inside", "outside"),
            SelectPlaneFar => ("select: batch vs far plane", "inside", "outside"),
            SelectFadeEnd => ("select: batch vs fade end (LOD0)", "no LOD0", "LOD0"),
            SelectFadeStart => ("select: batch vs fade start (LOD1)", "no LOD1", "LOD1"),
            RefineNeeded => (
                "refine: tree needed in its command's LOD",
                "dropped",
                "needed",
            ),
            RefineDrawDistance => ("refine: needed tree vs draw distance", "dropped", "kept"),
            CullDrawDistance => ("cull: tree vs draw distance", "within", "beyond"),
            CullFrustum => ("cull: tree vs frustum", "inside", "outside"),
            CullFadeEnd => ("cull: tree vs fade end (LOD0)", "no LOD0", "LOD0"),
            CullFadeStart => ("cull: tree vs fade start (LOD1)", "no LOD1", "LOD1"),
            CutVisited => ("cut: node visited", "not visited", "visited"),
            CutRecurse => ("cut: drawn interior node", "as one unit", "recurses"),
            CutCullSphereVsBox => (
                "cut: frustum cull by one bound alone",
                "sphere alone",
                "box alone",
            ),
            CutCullDepth => (
                "cut: octree interior node vs max_cull_depth",
                "above (tested)",
                "at/past (not tested)",
            ),
            CutPartial => (
                "cut: octree partial visibility",
                "box inside",
                "box straddles",
            ),
            CutPartialCentre => ("cut: partial test, box vs sphere centre", "agree", "differ"),
            CutEuclidean => (
                "cut: octree-euclidean box distance vs fade end",
                "nearer (recurse)",
                "at/past",
            ),
            DrawTreeDistance => ("draw: tree centre vs draw distance", "within", "beyond"),
            DrawMeshTreeDistance => (
                "draw: mesh tree centre vs draw distance",
                "within",
                "beyond",
            ),
            DrawAlphaCutoff => ("draw: texel alpha vs cutoff", "kept", "discarded"),
            DrawFadeStart => ("draw: fading fragment vs fade start", "before", "at/past"),
            DrawFadeEnd => ("draw: fading fragment vs fade end", "before", "at/past"),
            DrawDither => ("draw: dithered weight", "0 (discarded)", "1"),
            DrawTransitionId => ("draw: fading fragment's LOD id", "other", "transition"),
            SelectSubset => ("select: drawn batch's trees", "all", "a subset"),
            DrawSubsetDrop => ("draw: tree's subset weight", "above 0", "0 (dropped)"),
            DrawSubsetFade => ("draw: kept tree's subset weight", "whole", "fading"),
            DrawTreeProgress => (
                "draw: fading tree's own progress",
                "at a band end",
                "inside",
            ),
            DrawNoiseLevel => ("draw: texture-space noise level", "0 (finest)", "coarser"),
            DrawAzimuthRound => (
                "draw: billboard azimuth between two views",
                "nearer the lower",
                "nearer the upper",
            ),
            OccludeEarly => ("occlude: tree vs occluder rule", "late", "early"),
            OccludeLate => ("occlude: tested tree vs pyramid", "culled", "passes"),
            DrawOctahedralTriangle => (
                "draw: octahedral impostor's cell triangle",
                "lower",
                "upper",
            ),
            CutFar => ("cut: billboard node vs far rule", "stays", "far"),
            DrawFarAlpha => ("draw: far fragment alpha vs dither", "discarded", "kept"),
        }
    }
}

#[cfg(feature = "coverage")]
mod counters {
    use super::{ALL, Threshold};
    use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

    pub static ENABLED: AtomicBool = AtomicBool::new(false);
    #[allow(clippy::declare_interior_mutable_const)]
    const ZERO: AtomicU64 = AtomicU64::new(0);
    #[allow(clippy::declare_interior_mutable_const)]
    const ROW: [AtomicU64; 2] = [ZERO, ZERO];
    pub static COUNTS: [[AtomicU64; 2]; ALL.len()] = [ROW; ALL.len()];

    pub fn hit(t: Threshold, side: bool) {
        if ENABLED.load(Ordering::Relaxed) {
            COUNTS[t as usize][usize::from(side)].fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// Records that `t`'s side `side` was reached (only with the `coverage` feature, while enabled).
#[inline(always)]
pub fn hit(t: Threshold, side: bool) {
    #[cfg(feature = "coverage")]
    counters::hit(t, side);
    #[cfg(not(feature = "coverage"))]
    let _ = (t, side);
}

/// Whether counters are recording (the constant `false` without the `coverage` feature): guards
/// work done only to record (the per-plane tests of a batch).
#[inline(always)]
pub fn enabled() -> bool {
    #[cfg(feature = "coverage")]
    return counters::ENABLED.load(std::sync::atomic::Ordering::Relaxed);
    #[cfg(not(feature = "coverage"))]
    false
}

/// Zeroes the counters and starts recording. Panics without the `coverage` feature.
pub fn enable() {
    #[cfg(feature = "coverage")]
    {
        use std::sync::atomic::Ordering;
        for c in counters::COUNTS.iter().flatten() {
            c.store(0, Ordering::Relaxed);
        }
        counters::ENABLED.store(true, Ordering::SeqCst);
    }
    #[cfg(not(feature = "coverage"))]
    panic!("forestlod-shared was built without the `coverage` feature");
}

/// Stops recording and returns the counts since [`enable`], `[side false, side true]` per
/// threshold of [`ALL`].
pub fn disable() -> Vec<(Threshold, [u64; 2])> {
    #[cfg(feature = "coverage")]
    {
        use std::sync::atomic::Ordering;
        counters::ENABLED.store(false, Ordering::SeqCst);
        ALL.iter()
            .map(|&t| {
                let c = &counters::COUNTS[t as usize];
                (
                    t,
                    [c[0].load(Ordering::Relaxed), c[1].load(Ordering::Relaxed)],
                )
            })
            .collect()
    }
    #[cfg(not(feature = "coverage"))]
    ALL.iter().map(|&t| (t, [0, 0])).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn all_lists_every_threshold_once_in_order() {
        for (i, t) in ALL.iter().enumerate() {
            assert_eq!(*t as usize, i, "{t:?}");
        }
    }
}

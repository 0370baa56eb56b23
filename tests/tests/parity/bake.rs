//! Parity of the GPU `bake` stage (`gpu/src/shaders/bake.wgsl`) with the reference
//! (`reference/src/bake.rs`, `bake_layer`), SPEC §5.1 and §8: level 0 of every layer of the five
//! built-in species at K = 10, r = 64 and r = 128.
//!
//! One test body ([`check_bake`]) runs both backends of `forestlod_harness::texel_compare` and
//! judges every pixel of the GPU's layers against the reference's. A pixel may differ only where
//! the two are allowed to disagree, and each such pixel is classified and counted (SPEC §8,
//! dEQP-style), from the reference's own projected triangles (`bake_clip`):
//! - **edge-ambiguous**: its centre lies within [`EDGE_AMBIGUITY_PX`] of a projected triangle
//!   edge, so 8-bit subpixel snapping (and clip positions a few ulp apart) may cover it on one
//!   side and not on the other;
//! - **depth-ambiguous**: two triangles cover its centre with alpha > 0 at depths so close that
//!   the centre lies within the subpixel ambiguity of the line where their planes meet (or
//!   within [`DEPTH_SLACK`] for coplanar ones), so either may win the LESS test (the reference
//!   interpolates depth in `f64` from snapped vertices, the GPU in `f32`);
//! - **discard-ambiguous**: a covering triangle's bilinear alpha is positive at the uv
//!   interpolated from the snapped or from the unsnapped vertices but at most
//!   [`ALPHA_DISCARD_AMBIGUITY`] at the other (0 included), so one twin may keep the fragment and
//!   the other discard it: the GPU's quantized filter weights can give exactly 0, and the
//!   reference interpolates uv from the snapped vertices where lavapipe uses the unsnapped ones
//!   (measured below: pixels behind a fragment on the border of a transparent region, where the
//!   reference keeps an almost transparent fragment, writes its depth and hides what is behind);
//! - **filter-window**: the winning fragment is the same and both texels lie within ±1 of the
//!   range its bilinear sample spans over the uvs the fragment may be given: from the snapped
//!   and from the unsnapped vertices, each widened by the attribute's gradient times
//!   [`EDGE_AMBIGUITY_PX`] (the same subpixel ambiguity that moves a covered edge moves the point
//!   a vertex-interpolated uv is evaluated at, by at most `|∇uv| · δ`), with the filter fractions
//!   exact or moved to the neighbouring 1/[`FILTER_WEIGHT_STEPS`] (lavapipe quantizes bilinear
//!   weights to 8 bits; the reference does not). The widening matters where a quad is seen
//!   edge-on: the built-in trunks' crossed quads at the axis column map 16 (r = 128) to 80
//!   (r = 64) texels to a pixel, so `δ` moves the sample by 0.08 to 0.4 texels across the dark
//!   bark marks; the H200 showed 8 such pixels 2-4 bytes off the unwidened window (all explained
//!   by `|∇uv| · δ`, `tests::h200_bake_pixels_are_classified`). Measured, not assumed: the test
//!   reports how many pixels needed the window, their largest difference and the widest window
//!   (3 bytes at r = 128, 6 at r = 64 before the widening).
//!
//! Everything else must be within [`COLOR_TOLERANCE`] per channel; the largest difference and the
//! count of differing pixels of every class are reported. Then the full GPU path
//! (`GpuBake::bake`: bake, then the mips stage on the rendered texture) runs in every mode and is
//! compared with the reference's mips of the GPU's own level 0. Also: K = 1, 2 and r = 1, 2, 4
//! (SPEC §7), azimuth views (issue 30, E§7: J = 4 at K = 2, every view's triangles projected by
//! the reference's `bake_clip_view`, judged by the same classes), and the stage's input errors.
//!
//! Measured on lavapipe (K = 10): r = 128: 121718 of 819200 pixels differ by 1, 5 edge-, 1622
//! depth-, 53 discard-ambiguous, 40 in the filter window (max difference 3); r = 64: 31153 by 1,
//! 7 edge-, 619 depth-, 26 discard-ambiguous, 78 in the filter window (max difference 4); none
//! unexplained.

use std::time::Instant;

use forestlod_gpu::GpuError;
use forestlod_harness::stage::{Backend, Bake, BakeInput, Mips, MipsInput, Reference};
use forestlod_harness::stats::SignedHistogram;
use forestlod_harness::texel_compare::{
    GpuBakeBackend, MIPS_BIAS_MAX, TEXEL_BIAS_MAX, TexelTally, bake_mesh, channel_diff, gpu_bake,
};
use forestlod_reference::bake::bake_clip_view;
use forestlod_reference::sampler::Texture;
use forestlod_reference::scene::TreeMesh;
use forestlod_reference::scene::builtin::species_meshes;
use forestlod_reference::texture::{Rgba8Image, linear_to_srgb, unorm8};
use forestlod_shared::{BillboardViews, MeshMeta, MipMode, Params, bake_azimuth, bake_elevation};

/// Per-channel tolerance for pixels in no ambiguity class.
///
/// Why ±1: both sides write the same linear colour into an `Rgba8UnormSrgb` target, but the GPU's
/// sRGB encode (and its bilinear filter's arithmetic) rounds independently of the reference's
/// exact `f64` encode, so a value near a byte boundary may land one step apart (SPEC §8). Measured:
/// about 15 % of the pixels differ, never by more than 1 outside the ambiguity classes.
const COLOR_TOLERANCE: u8 = 1;

/// Per-channel tolerance of the mips stage run on the GPU's baked layers (as in
/// `parity/mips.rs`): quantization is exact on both sides, the alpha-weighted colour may round a
/// few ulp apart and land one byte away.
const MIP_TEXEL_TOLERANCE: u8 = 1;

/// Distance in pixels from a pixel centre to a projected edge within which coverage may differ.
///
/// Why 1/256 px plus 1/1024: the rasterizer snaps vertices to 8 subpixel bits (SPEC §3), so an
/// edge moves by up to half a subpixel at each end; a clip position a few ulp off (fused
/// multiply-add in `bake_clip`) can round to the neighbouring subpixel, one more 1/256. The extra
/// 1/1024 px covers the `f64` distance computed here from the unsnapped `f32` positions.
const EDGE_AMBIGUITY_PX: f64 = 1.0 / 256.0 + 1.0 / 1024.0;

/// Depth slack, beyond the subpixel term, within which two fragments of one pixel may win the
/// LESS test either way.
///
/// Two fragments are depth-ambiguous when `|z_a - z_b| <= (|∇z_a| + |∇z_b|) · EDGE_AMBIGUITY_PX +
/// DEPTH_SLACK`, i.e. when the pixel centre lies within the subpixel ambiguity of the line where
/// the two planes meet. The gradient term: the reference interpolates depth from the *snapped*
/// vertices (in `f64`), a GPU may interpolate from the unsnapped ones, and snapping moves a vertex
/// by up to 1/512 px. The slack: coplanar or nearly coplanar triangles (crossed cards meeting on
/// the trunk axis) tie up to the rounding of the interpolation itself, a few ulp of depths in
/// `[0, 1]` (measured on the built-in species at r = 128: gaps up to 7e-8, one ulp; at r = 64 up
/// to 1.2e-4 on steep triangles, inside the gradient term); 8 ulp of 1.0 (~1e-6) covers the
/// former, and a real depth-test bug (wrong compare, no depth) differs by far more.
const DEPTH_SLACK: f64 = 8.0 * f32::EPSILON as f64;

/// Bilinear alpha at or below which a fragment may be discarded by one side and kept by the
/// other.
///
/// Why 1/256: the GPU rounds each bilinear weight to a multiple of 1/256; a texel whose exact
/// weight is below 1/512 along one axis then weighs 0, so a sample whose only positive-alpha texel
/// sits there has reference alpha below 1/512 (times at most 1) but GPU alpha 0. Doubling gives
/// margin for the rounding direction.
const ALPHA_DISCARD_AMBIGUITY: f32 = 1.0 / 256.0;

/// Subtexel steps per texel of the GPU's bilinear weights (lavapipe: 8 bits).
const FILTER_WEIGHT_STEPS: f32 = 256.0;

/// One triangle projected into the layer's framebuffer (pixels, y down), with its depth and uvs.
#[derive(Clone, Copy, Debug)]
struct Projected {
    p: [[f64; 2]; 3],
    z: [f64; 3],
    uv: [[f64; 2]; 3],
}

fn project(
    mesh: &TreeMesh,
    meta: &MeshMeta,
    views: BillboardViews,
    (k, j): (u32, u32),
    r: u32,
) -> Vec<Projected> {
    let e = bake_elevation(k, views.angle_count);
    let (sin_a, cos_a) = bake_azimuth(j, views.azimuth_count).sin_cos();
    // Octahedral frames (issue 32): frame `k` of the grid.
    let frame = views.octahedral().then(|| {
        forestlod_shared::frame_direction(
            k,
            views.grid,
            forestlod_shared::octahedral::is_hemi(views.sphere),
        )
    });
    let clip = |p: [f32; 3]| match frame {
        Some(d) => forestlod_reference::bake::octahedral_clip(p, meta, d),
        None => bake_clip_view(p, meta, e, sin_a, cos_a),
    };
    let r = f64::from(r);
    mesh.indices
        .chunks_exact(3)
        .map(|t| {
            let v = |i: usize| {
                let c = clip(mesh.positions[t[i] as usize]);
                let x = (f64::from(c[0]) + 1.0) * 0.5 * r;
                let y = (1.0 - f64::from(c[1])) * 0.5 * r;
                (
                    [x, y],
                    f64::from(c[2]),
                    mesh.uvs[t[i] as usize].map(f64::from),
                )
            };
            let (a, b, c) = (v(0), v(1), v(2));
            Projected {
                p: [a.0, b.0, c.0],
                z: [a.1, b.1, c.1],
                uv: [a.2, b.2, c.2],
            }
        })
        .collect()
}

fn cross(o: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
}

fn segment_distance(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let (x, y) = (a[0] + t * dx - p[0], a[1] + t * dy - p[1]);
    (x * x + y * y).sqrt()
}

/// Barycentrics of `p` in `t` (possibly negative), if the triangle has area.
fn barycentrics_unclosed(t: &Projected, p: [f64; 2]) -> Option<[f64; 3]> {
    let area = cross(t.p[0], t.p[1], t.p[2]);
    (area != 0.0).then(|| {
        [
            cross(t.p[1], t.p[2], p) / area,
            cross(t.p[2], t.p[0], p) / area,
            cross(t.p[0], t.p[1], p) / area,
        ]
    })
}

/// Barycentrics of `p` in `t` if `p` is inside (closed) and the triangle has area.
fn barycentrics(t: &Projected, p: [f64; 2]) -> Option<[f64; 3]> {
    barycentrics_unclosed(t, p).filter(|l| l.iter().all(|&v| v >= 0.0))
}

/// `|∇f|` per pixel of the attribute with vertex values `f` over a projected triangle.
fn gradient(t: &Projected, f: [f64; 3]) -> f64 {
    let [p0, p1, p2] = t.p;
    let area = cross(p0, p1, p2);
    let (d1, d2) = (f[1] - f[0], f[2] - f[0]);
    let dx = (d1 * (p2[1] - p0[1]) - d2 * (p1[1] - p0[1])) / area;
    let dy = (d2 * (p1[0] - p0[0]) - d1 * (p2[0] - p0[0])) / area;
    (dx * dx + dy * dy).sqrt()
}

/// A covering triangle's fragment at a pixel centre, as the reference computes it.
struct Candidate {
    depth: f64,
    /// `|∇z|` in depth per pixel.
    slope: f64,
    uv: [f32; 2],
    /// The uv interpolated from the snapped vertices, as the reference rasterizer does (a GPU
    /// may interpolate from the unsnapped ones, `uv`).
    uv_snapped: [f32; 2],
    /// Bilinear alpha at `uv`.
    alpha: f32,
    /// Bilinear alpha at `uv_snapped`.
    alpha_snapped: f32,
    /// How far the uv may move with the point it is evaluated at: `|∇u| δ`, `|∇v| δ` with
    /// `δ` = [`EDGE_AMBIGUITY_PX`] (module docs, filter-window).
    uv_reach: [f64; 2],
}

fn candidates(tris: &[Projected], texture: &Texture, p: [f64; 2]) -> Vec<Candidate> {
    tris.iter()
        .filter_map(|t| {
            let l = barycentrics(t, p)?;
            let depth = l[0] * t.z[0] + l[1] * t.z[1] + l[2] * t.z[2];
            let slope = gradient(t, t.z);
            // The reference interpolates from the snapped vertices (8 subpixel bits).
            let snapped = Projected {
                p: t.p
                    .map(|v| v.map(|c| (c * 256.0).round_ties_even() / 256.0)),
                ..*t
            };
            let uv_snapped = barycentrics_unclosed(&snapped, p).map(|l| {
                [0, 1].map(|c| (l[0] * t.uv[0][c] + l[1] * t.uv[1][c] + l[2] * t.uv[2][c]) as f32)
            });
            let uv =
                [0, 1].map(|c| (l[0] * t.uv[0][c] + l[1] * t.uv[1][c] + l[2] * t.uv[2][c]) as f32);
            let uv_snapped = uv_snapped.unwrap_or(uv);
            let uv_reach = [0, 1]
                .map(|c| gradient(t, [t.uv[0][c], t.uv[1][c], t.uv[2][c]]) * EDGE_AMBIGUITY_PX);
            Some(Candidate {
                depth,
                slope,
                uv,
                uv_snapped,
                alpha: texture.bilinear(0, 0, uv)[3],
                alpha_snapped: texture.bilinear(0, 0, uv_snapped)[3],
                uv_reach,
            })
        })
        .collect()
}

/// The range of bytes the reference's bilinear sample can take within the filter's and the
/// interpolation's ambiguity: over the uv box `[lo, hi]` (the uvs interpolated from the snapped
/// and from the unsnapped vertices, widened by [`Candidate::uv_reach`]), each filter fraction
/// either exact or moved to the neighbouring multiple of `1 / FILTER_WEIGHT_STEPS`. The bilinear
/// sample is bilinear inside each texel cell, so its extremes over the box lie where the box's
/// edges and the texel-centre lines inside it cross: those are the points evaluated.
fn filter_window(texture: &Texture, lo: [f32; 2], hi: [f32; 2]) -> ([u8; 4], [u8; 4]) {
    let img = texture.level(0, 0);
    let steps = |f: f32| {
        let s = f * FILTER_WEIGHT_STEPS;
        [
            f,
            s.floor() / FILTER_WEIGHT_STEPS,
            s.ceil() / FILTER_WEIGHT_STEPS,
        ]
    };
    // Texel-space coordinates of the box's edges and of the texel-centre lines between them.
    let coords = |a: f32, b: f32, size: u32| -> Vec<f32> {
        let (a, b) = (a * size as f32 - 0.5, b * size as f32 - 0.5);
        let mut c = vec![a, b];
        let mut k = a.floor() + 1.0;
        while k < b {
            c.push(k);
            k += 1.0;
        }
        c
    };
    let (mut out_lo, mut out_hi) = ([255u8; 4], [0u8; 4]);
    for u in coords(lo[0], hi[0], img.width) {
        for v in coords(lo[1], hi[1], img.height) {
            let (fu, fv) = (u.floor(), v.floor());
            let (i0, j0) = (fu as i64, fv as i64);
            let t = [
                texture.texel(0, 0, i0, j0),
                texture.texel(0, 0, i0 + 1, j0),
                texture.texel(0, 0, i0, j0 + 1),
                texture.texel(0, 0, i0 + 1, j0 + 1),
            ];
            for a in steps(u - fu) {
                for b in steps(v - fv) {
                    let w = [(1.0 - a) * (1.0 - b), a * (1.0 - b), (1.0 - a) * b, a * b];
                    for c in 0..4 {
                        let x = w[0] * t[0][c] + w[1] * t[1][c] + w[2] * t[2][c] + w[3] * t[3][c];
                        let byte = if c == 3 { unorm8(x) } else { linear_to_srgb(x) };
                        out_lo[c] = out_lo[c].min(byte);
                        out_hi[c] = out_hi[c].max(byte);
                    }
                }
            }
        }
    }
    (out_lo, out_hi)
}

/// Why a differing pixel may differ, or `None`.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Class {
    Edge,
    /// The largest depth gap between the winner and a tied fragment.
    Depth(f64),
    Discard,
    /// Within ±1 of the reference's filter window; the payload is the window's width in bytes.
    FilterWindow(u8),
}

fn classify(
    tris: &[Projected],
    texture: &Texture,
    x: u32,
    y: u32,
    got: [u8; 4],
    want: [u8; 4],
) -> Option<Class> {
    let p = [f64::from(x) + 0.5, f64::from(y) + 0.5];
    let near_edge = tris.iter().any(|t| {
        (0..3).any(|i| segment_distance(p, t.p[i], t.p[(i + 1) % 3]) <= EDGE_AMBIGUITY_PX)
    });
    if near_edge {
        return Some(Class::Edge);
    }
    let cands = candidates(tris, texture, p);
    // Kept by one interpolation or filter and possibly discarded by the other.
    if cands.iter().any(|c| {
        let (lo, hi) = (c.alpha.min(c.alpha_snapped), c.alpha.max(c.alpha_snapped));
        hi > 0.0 && lo <= ALPHA_DISCARD_AMBIGUITY
    }) {
        return Some(Class::Discard);
    }
    let kept: Vec<&Candidate> = cands.iter().filter(|c| c.alpha > 0.0).collect();
    let tie = |a: &Candidate, b: &Candidate| {
        (a.depth - b.depth).abs() <= (a.slope + b.slope) * EDGE_AMBIGUITY_PX + DEPTH_SLACK
    };
    let nearest = kept.iter().map(|c| c.depth).fold(f64::INFINITY, f64::min);
    // The winner: submission order breaks exact ties, as LESS keeps the first.
    let winner = kept.iter().find(|c| c.depth == nearest)?;
    if let Some(gap) = kept
        .iter()
        .filter(|c| !std::ptr::eq(**c, *winner) && tie(c, winner))
        .map(|c| (c.depth - winner.depth).abs())
        .reduce(f64::max)
    {
        return Some(Class::Depth(gap));
    }
    let (box_lo, box_hi): ([f32; 2], [f32; 2]) = (
        [0, 1].map(|c| {
            (f64::from(winner.uv[c].min(winner.uv_snapped[c])) - winner.uv_reach[c]) as f32
        }),
        [0, 1].map(|c| {
            (f64::from(winner.uv[c].max(winner.uv_snapped[c])) + winner.uv_reach[c]) as f32
        }),
    );
    let (lo, hi) = filter_window(texture, box_lo, box_hi);
    // Both twins must show the same fragment: each texel within ±1 of its window.
    let inside = |t: [u8; 4]| {
        (0..4).all(|c| {
            t[c].saturating_add(COLOR_TOLERANCE) >= lo[c]
                && t[c] <= hi[c].saturating_add(COLOR_TOLERANCE)
        })
    };
    let within = inside(got) && inside(want);
    within.then(|| Class::FilterWindow((0..4).map(|c| hi[c] - lo[c]).max().unwrap_or(0)))
}

/// Tallies of a bake comparison.
#[derive(Default, Debug)]
struct BakeTally {
    layers: u64,
    pixels: u64,
    /// Pixels with alpha > 0 in the reference (a blank bake would compare equal trivially).
    covered: u64,
    /// Differing pixels within `COLOR_TOLERANCE`.
    within_tolerance: u64,
    max_diff_within: u8,
    edge: u64,
    depth: u64,
    /// Largest depth gap a depth-ambiguous pixel needed.
    max_depth_gap: f64,
    discard: u64,
    filter_window: u64,
    /// Largest difference of a filter-window pixel.
    max_diff_filter_window: u8,
    /// Largest window width (bytes) a filter-window pixel needed.
    max_filter_window: u8,
    /// Largest difference over all classified pixels.
    max_diff_classified: u8,
    failures: Vec<String>,
    /// Signed differences (GPU minus reference) per channel over the pixels within
    /// [`COLOR_TOLERANCE`] at the same position, equal ones included (statistical parity).
    signed: [SignedHistogram; 4],
}

/// The one test body: both backends bake `meshes`; the GPU judged pixel by pixel.
fn check_bake(
    gpu: &dyn Backend<Bake>,
    meshes: &[TreeMesh],
    views: BillboardViews,
    r: u32,
) -> (BakeTally, Vec<Rgba8Image>) {
    let input = BakeInput {
        meshes,
        angle_count: views.angle_count,
        azimuth_count: views.azimuth_count,
        sphere: views.sphere,
        grid: views.grid,
        side: r,
        depth: false,
    };
    let order: Vec<(usize, u32, u32)> = views.views(meshes.len()).collect();
    let want = Backend::<Bake>::run(&Reference, input);
    let got = gpu.run(input);
    assert_eq!(got.len(), want.len());
    let mut tally = BakeTally::default();
    for (layer, (g, w)) in got.iter().zip(&want).enumerate() {
        let (m, k, j) = order[layer];
        let mesh = &meshes[m];
        let tris = project(mesh, &mesh.meta(), views, (k, j), r);
        let texture = Texture::new(vec![mesh.texture.clone()]).unwrap();
        tally.layers += 1;
        for y in 0..r {
            for x in 0..r {
                tally.pixels += 1;
                let (gt, wt) = (g.get(x, y), w.get(x, y));
                tally.covered += u64::from(wt[3] > 0);
                let d = channel_diff(gt, wt);
                if d <= COLOR_TOLERANCE {
                    for (c, h) in tally.signed.iter_mut().enumerate() {
                        h.tolerance = i64::from(COLOR_TOLERANCE);
                        h.record_at(i64::from(wt[c]), i64::from(gt[c]) - i64::from(wt[c]));
                    }
                }
                if d == 0 {
                    continue;
                }
                if d <= COLOR_TOLERANCE {
                    tally.within_tolerance += 1;
                    tally.max_diff_within = tally.max_diff_within.max(d);
                    continue;
                }
                match classify(&tris, &texture, x, y, gt, wt) {
                    Some(class) => {
                        tally.max_diff_classified = tally.max_diff_classified.max(d);
                        match class {
                            Class::Edge => tally.edge += 1,
                            Class::Depth(gap) => {
                                tally.depth += 1;
                                tally.max_depth_gap = tally.max_depth_gap.max(gap);
                            }
                            Class::Discard => tally.discard += 1,
                            Class::FilterWindow(w) => {
                                tally.filter_window += 1;
                                tally.max_diff_filter_window = tally.max_diff_filter_window.max(d);
                                tally.max_filter_window = tally.max_filter_window.max(w);
                            }
                        }
                    }
                    None => {
                        if tally.failures.len() < 20 {
                            tally.failures.push(format!(
                                "layer {layer} (mesh {m}, k {k}, j {j}) pixel ({x}, {y}): gpu {gt:?} reference {wt:?}"
                            ));
                        } else {
                            tally.failures.push(String::new());
                        }
                    }
                }
            }
        }
    }
    (tally, got)
}

/// Prints a bake tally and fails on unexplained pixels.
fn report(what: &str, tally: &BakeTally, started: Instant) {
    let failures = tally.failures.len();
    eprintln!(
        "{what}: {} layers, {} pixels ({} covered in the reference): {} differ within \
         ±{COLOR_TOLERANCE} (max {}), {} edge-ambiguous, {} depth-ambiguous (largest gap \
         {:.3e}), {} discard-ambiguous, {} in the filter window (max difference {}, widest window {} bytes); max difference \
         of classified pixels {}; {failures} unexplained; {:.2} s",
        tally.layers,
        tally.pixels,
        tally.covered,
        tally.within_tolerance,
        tally.max_diff_within,
        tally.edge,
        tally.depth,
        tally.max_depth_gap,
        tally.discard,
        tally.filter_window,
        tally.max_diff_filter_window,
        tally.max_filter_window,
        tally.max_diff_classified,
        started.elapsed().as_secs_f64()
    );
    for (h, c) in tally.signed.iter().zip(["R", "G", "B", "A"]) {
        eprintln!("  {c}: {h}");
    }
    for f in tally.failures.iter().filter(|f| !f.is_empty()) {
        eprintln!("  {f}");
    }
    let biased: Vec<String> = tally
        .signed
        .iter()
        .zip(["R", "G", "B", "A"])
        .filter_map(|(h, c)| h.value_bias_failure(&format!("{what} channel {c}"), TEXEL_BIAS_MAX))
        .collect();
    assert!(biased.is_empty(), "biased bake:\n{}", biased.join("\n"));
    assert_eq!(
        failures, 0,
        "{what}: {failures} pixels differ beyond tolerance outside every ambiguity class"
    );
}

/// The five species at `angle_count`, `r`: level 0 judged pixel by pixel; then the full GPU path
/// (`GpuBake::bake`: bake, then mips on the rendered texture) in every mode against the
/// reference's mips of the GPU's own level 0.
fn run(angle_count: u32, r: u32, full_path: bool) {
    run_views(BillboardViews::elevations(angle_count), r, full_path);
}

/// [`run`] with `views` (azimuth views too, issue 30).
fn run_views(views: BillboardViews, r: u32, full_path: bool) {
    let Some(bake) = gpu_bake() else {
        eprintln!("skipped, no GPU adapter");
        return;
    };
    let started = Instant::now();
    let meshes = species_meshes();
    let (angle_count, azimuth_count) = (views.angle_count, views.azimuth_count);
    let what = format!("bake K={angle_count} J={azimuth_count} r={r}");
    let (tally, gpu_layers) = check_bake(&GpuBakeBackend { bake }, &meshes, views, r);
    report(&what, &tally, started);
    if !full_path {
        return;
    }
    let ctx = bake.mips().context();
    let inputs: Vec<_> = meshes.iter().map(bake_mesh).collect();
    for mode in MipMode::ALL {
        let params = Params {
            angle_count,
            azimuth_count,
            billboard_views: views.sphere,
            octahedral_grid: views.grid.max(forestlod_shared::MIN_OCTAHEDRAL_GRID),
            texture_size: r,
            mip_mode: mode as u32,
            alpha_cutoff: 0.5,
            ..Params::default()
        };
        let baked = bake.bake(&inputs, &params).expect("GpuBake::bake");
        assert_eq!(baked.extents.len(), gpu_layers.len());
        let chains = baked.mips.read_chains(ctx).expect("read chains");
        let want = Backend::<Mips>::run(
            &Reference,
            MipsInput {
                layers: &gpu_layers,
                mode,
                alpha_ref: params.alpha_cutoff,
            },
        );
        let mut texels = TexelTally::default();
        for (layer, (g, w)) in chains.iter().zip(&want).enumerate() {
            assert_eq!(
                g[0].texels, gpu_layers[layer].texels,
                "layer {layer}: level 0 of GpuBake::bake differs from GpuBake::bake_level0"
            );
            for (k, (gl, wl)) in g.iter().zip(w).enumerate() {
                texels.compare(
                    &format!("layer {layer} level {k}"),
                    &gl.texels,
                    &wl.image.texels,
                    MIP_TEXEL_TOLERANCE,
                );
            }
        }
        eprintln!(
            "{what}, GpuBake::bake then mips ({}) vs reference mips of the GPU's level 0: {}",
            mode.name(),
            texels.summary()
        );
        assert_eq!(texels.over_tolerance, 0, "{:?}", texels.first_over);
        let biased = texels.bias_failures(&format!("{what} {}", mode.name()), MIPS_BIAS_MAX);
        assert!(biased.is_empty(), "biased mips:\n{}", biased.join("\n"));
    }
    eprintln!("{what}: {:.2} s in all", started.elapsed().as_secs_f64());
}

#[test]
fn gpu_bake_equals_the_reference_r64() {
    run(10, 64, true);
}

#[test]
fn gpu_bake_equals_the_reference_r128() {
    run(10, 128, true);
}

/// Issue 30 (E§7): four azimuth views of two elevations, every view judged by the classes above
/// against the reference's projection of that view; then the full path (bake and mips).
#[test]
fn gpu_bake_equals_the_reference_with_azimuths() {
    let views = BillboardViews {
        angle_count: 2,
        azimuth_count: 4,
        ..BillboardViews::elevations(2)
    };
    run_views(views, 64, true);
}

/// Issue 32: octahedral frames (a 4x4 hemi-octahedral grid and a 4x4 full one, whose rim frames
/// look from below), every frame judged by the classes above against the reference's projection
/// of that frame; then the full path (bake and mips) for the hemi grid. At r = 128: at r = 64 the
/// frames' fewer covered texels hold fewer distinct values, and lavapipe's known per-element
/// lean (green up, blue down: [`TEXEL_BIAS_MAX`]'s note; +0.08 green on the azimuth views above)
/// tipped green's per-value sign test (88 of 104 values up on a 2x2 hemi grid, 1,088 texels);
/// at r = 128 the full grid measures +0.055 per value, 111 up and 52 down, the azimuth views'
/// +0.057, 105 up and 46 down.
#[test]
fn gpu_bake_equals_the_reference_with_octahedral_frames() {
    for (sphere, grid, full) in [
        (forestlod_shared::ViewSphere::HemiOctahedral, 4, true),
        (forestlod_shared::ViewSphere::Octahedral, 4, false),
    ] {
        let views = BillboardViews {
            sphere: sphere as u32,
            grid,
            ..BillboardViews::elevations(1)
        };
        run_views(views, 128, full);
    }
}

#[test]
fn gpu_bake_equals_the_reference_at_the_extremes() {
    // SPEC §7: r = 1, 2, 4 and K = 1 (the level view only), 2.
    for angle_count in [1, 2] {
        for r in [1, 2, 4] {
            run(angle_count, r, false);
        }
    }
    // Octahedral frames (issue 32) at the same sides: a 2x2 hemi grid and a 3x3 full one.
    for (sphere, grid) in [
        (forestlod_shared::ViewSphere::HemiOctahedral, 2),
        (forestlod_shared::ViewSphere::Octahedral, 3),
    ] {
        for r in [1, 2, 4] {
            let views = BillboardViews {
                sphere: sphere as u32,
                grid,
                ..BillboardViews::elevations(1)
            };
            run_views(views, r, false);
        }
    }
}

#[test]
fn gpu_bake_rejects_bad_inputs() {
    let Some(bake) = gpu_bake() else {
        eprintln!("skipped, no GPU adapter");
        return;
    };
    let meshes = species_meshes();
    let inputs: Vec<_> = meshes.iter().map(bake_mesh).collect();
    for (k, r) in [(10, 100), (10, 0), (0, 64), (10, 8192)] {
        let err = bake
            .bake_level0(&inputs, BillboardViews::elevations(k), r)
            .unwrap_err();
        eprintln!("K={k} r={r}: {err}");
        assert!(matches!(err, GpuError::Input { .. }), "{err}");
    }
    // No azimuth view (issue 30).
    let none = BillboardViews {
        angle_count: 10,
        azimuth_count: 0,
        ..BillboardViews::elevations(10)
    };
    let err = bake.bake_level0(&inputs, none, 64).unwrap_err();
    assert!(err.to_string().contains("0 azimuths"), "{err}");
    let mut broken = inputs[0];
    let bad = [0u32, 1, 999];
    broken.indices = &bad;
    let err = bake
        .bake_level0(&[broken], BillboardViews::elevations(1), 8)
        .unwrap_err();
    assert!(err.to_string().contains("999"), "{err}");
    let err = bake
        .mips()
        .run_from_cpu(4, &[&[[0u8; 4]; 15][..]], MipMode::AlphaAware, 0.5)
        .unwrap_err();
    assert!(err.to_string().contains("15 texels"), "{err}");
    let err = bake
        .mips()
        .run_from_cpu(4, &[&[[0u8; 4]; 16][..]], MipMode::AlphaAware, f32::NAN)
        .unwrap_err();
    assert!(err.to_string().contains("alpha_ref"), "{err}");
}

/// The H200's unexplained bake pixels (`experiments/results/gpu_check_h200/`, driver
/// 580.159.04, K = 10), classified here from the logged values on the reference's own
/// triangles (no adapter needed): the eight at the trunk's axis column, where an edge-on quad
/// maps 16 to 80 texels to a pixel, lie within the filter window once the uv is allowed to move
/// with the subpixel ambiguity (module docs, filter-window); the ninth (r = 64, layer 30, pixel
/// (31, 38): GPU `[45, 40, 36]`, reference `[46, 43, 40]`) does not: its blue lies 2 below every
/// texel the footprint can reach (the dark bark mark is `[44, 40, 38]`, the light bark around it
/// bluer still), which no filter position or weight rounding explains. It is left unexplained
/// (the r = 64 test still fails on the H200 with this one pixel) rather than forgiven by a wider
/// class. Mutation-checked: without the widening (`uv_reach` 0) the eight are unexplained.
#[test]
fn h200_bake_pixels_are_classified() {
    /// A logged pixel: r, layer, x, y, GPU, reference, explained here.
    type Logged = (u32, u32, u32, u32, [u8; 4], [u8; 4], bool);
    let meshes = species_meshes();
    let logged: [Logged; 9] = [
        (128, 30, 64, 73, [48, 44, 42, 255], [50, 47, 44, 255], true),
        (128, 32, 63, 82, [67, 64, 59, 255], [68, 65, 62, 255], true),
        (128, 32, 65, 88, [53, 49, 47, 255], [54, 51, 48, 255], true),
        (128, 34, 63, 96, [65, 62, 57, 255], [66, 63, 59, 255], true),
        (128, 35, 63, 91, [92, 89, 83, 255], [93, 90, 85, 255], true),
        (128, 36, 63, 87, [64, 60, 56, 255], [65, 62, 58, 255], true),
        (64, 30, 31, 38, [45, 40, 36, 255], [46, 43, 40, 255], false),
        (64, 32, 31, 37, [50, 47, 42, 255], [52, 49, 46, 255], true),
        (
            64,
            34,
            31,
            36,
            [103, 101, 94, 255],
            [104, 101, 96, 255],
            true,
        ),
    ];
    for (r, layer, x, y, got, want, explained) in logged {
        let (m, k) = (layer as usize / 10, layer % 10);
        let mesh = &meshes[m];
        let views = BillboardViews::elevations(10);
        let tris = project(mesh, &mesh.meta(), views, (k, 0), r);
        let texture = Texture::new(vec![mesh.texture.clone()]).unwrap();
        let class = classify(&tris, &texture, x, y, got, want);
        eprintln!("r {r} layer {layer} ({x}, {y}): GPU {got:?}, reference {want:?}: {class:?}");
        if explained {
            assert!(
                matches!(class, Some(Class::FilterWindow(_))),
                "r {r} layer {layer} ({x}, {y}): {class:?}"
            );
        } else {
            assert_eq!(class, None, "r {r} layer {layer} ({x}, {y})");
        }
    }
}

/// Red difference allowed between the twins' depth layers where both keep a fragment (issue 32's
/// depth channel): the reference interpolates depth in `f64` from snapped vertices, the GPU in
/// `f32`, and both round the sRGB encoding of `z` to 8 bits, so a depth on a rounding boundary
/// may land one byte apart.
const DEPTH_RED_TOLERANCE: u8 = 1;

/// Fraction of the covered pixels allowed to differ beyond [`DEPTH_RED_TOLERANCE`] or in
/// coverage: the colour bake's ambiguity classes (edge-, depth- and discard-ambiguous pixels,
/// 0.35 % of the pixels at r = 64 above) apply to the depth render unchanged, and where a
/// depth-ambiguous pixel picks the other triangle its depth differs by that triangle's offset,
/// not by a byte. The depth layers are not re-classified pixel by pixel: the colour layers of the
/// same renders are (above). Measured on lavapipe: 22 of 36,084 covered pixels (0.061 %), the
/// largest red difference 33; the rest within 1.
const DEPTH_MAX_EXCEPTION_FRACTION: f64 = 0.02;

/// Issue 32's depth channel: the GPU's `bake_depth_fs` layers against the reference's
/// `bake_depth_view` (a 4x4 hemi-octahedral grid of the five species at r = 64). On each
/// backend a depth layer's alpha equals its colour layer's exactly (the same render keeps the
/// same fragments); across backends the red depth agrees within [`DEPTH_RED_TOLERANCE`] except
/// on at most [`DEPTH_MAX_EXCEPTION_FRACTION`] of the covered pixels. Mutation-checked: red
/// written as `1 - z` in `bake_depth_fs` fails the cross-backend bound.
#[test]
fn gpu_depth_channel_equals_the_reference() {
    let Some(bake) = gpu_bake() else {
        eprintln!("skipped, no GPU adapter");
        return;
    };
    let r = 64;
    let meshes = species_meshes();
    let views = BillboardViews {
        sphere: forestlod_shared::ViewSphere::HemiOctahedral as u32,
        grid: 4,
        ..BillboardViews::elevations(1)
    };
    let ctx = bake.mips().context();
    let inputs: Vec<_> = meshes.iter().map(bake_mesh).collect();
    let read = |t: wgpu::Texture| {
        forestlod_gpu::MipArray::from_texture(ctx, t, MipMode::Box, 0.5)
            .expect("wrap")
            .read_level0(ctx)
            .expect("read level 0")
    };
    let gpu_depth = read(
        bake.bake_depth_level0(&inputs, views, r)
            .expect("depth bake"),
    );
    let gpu_color = read(bake.bake_level0(&inputs, views, r).expect("colour bake"));
    let order: Vec<(usize, u32, u32)> = views.views(meshes.len()).collect();
    let (mut covered, mut exceptions, mut max_within, mut max_any) = (0u64, 0u64, 0u8, 0u8);
    for (layer, &(m, f, _)) in order.iter().enumerate() {
        let mesh = &meshes[m];
        let texture = Texture::new(vec![mesh.texture.clone()]).unwrap();
        let meta = mesh.meta();
        let want = forestlod_reference::bake::bake_depth_view(mesh, &meta, &texture, views, f, r);
        let want_color =
            forestlod_reference::bake::bake_view(mesh, &meta, &texture, views, f, 0, r);
        for (i, (g, w)) in gpu_depth[layer].texels.iter().zip(&want.texels).enumerate() {
            assert_eq!(
                g[3], gpu_color[layer].texels[i][3],
                "GPU layer {layer} texel {i}: depth alpha != colour alpha"
            );
            assert_eq!(
                w[3], want_color.texels[i][3],
                "reference layer {layer} texel {i}: depth alpha != colour alpha"
            );
            if g[3] == 0 && w[3] == 0 {
                continue;
            }
            covered += 1;
            let d = g[0].abs_diff(w[0]);
            max_any = max_any.max(d);
            if g[3] == 0 || w[3] == 0 || d > DEPTH_RED_TOLERANCE {
                exceptions += 1;
            } else {
                max_within = max_within.max(d);
            }
        }
    }
    let fraction = exceptions as f64 / covered.max(1) as f64;
    eprintln!(
        "depth channel, {} layers at r = {r}: {covered} covered pixels, {exceptions} ({:.3} %) \
         beyond ±{DEPTH_RED_TOLERANCE} or differently covered (largest red difference {max_any}), \
         the rest within {max_within}",
        order.len(),
        100.0 * fraction
    );
    assert!(covered > 1000, "only {covered} covered pixels");
    assert!(
        fraction <= DEPTH_MAX_EXCEPTION_FRACTION,
        "{:.3} % of the covered pixels differ (bound {} %)",
        100.0 * fraction,
        100.0 * DEPTH_MAX_EXCEPTION_FRACTION
    );
}

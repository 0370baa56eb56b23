//! Triangle setup (module docs, steps 1-5): clipping (near and far exactly, x and y at the guard
//! band), the viewport transform, snapping to [`SUBPIXEL_BITS`], facing and culling, the top-left
//! edge rules, the pixel box and the depth lower bound; and the exact integer edge-function
//! arithmetic the tile walk uses (`SetupTriangle::edges`, `edge_steps`, `quad_edges`,
//! `covered_quad_span`), plus the rounding helpers that replace libm calls.
//!
//! Invariants:
//! - watertight: the clipper interpolates from the vertex inside a plane towards the one
//!   outside, so a shared edge is cut at bit-identical points from both sides;
//! - exact coverage: snapped coordinates satisfy `|X|, |Y| <= MAX_ABS_FIXED < 2^30`, so edge
//!   functions fit `i64` (checked at compile time); a polygon beyond it, or a triangle with a
//!   non-finite clip coordinate, is dropped;
//! - a kept `SetupTriangle` has positive area and a pixel box holding at least one pixel centre
//!   of the target; its `min_depth` is at most its depth at every sample it covers
//!   (`depth_lower_bound`);
//! - the stepped edge functions (`quad_edges`) and the covered spans (`covered_quad_span`) equal
//!   the directly evaluated edge functions exactly (tests below);
//! - `round_ties_even_exact` and `round_exact` equal the standard library bit for bit.
//!
//! Depends on `types` and `target` ([`MAX_TARGET_SIZE`]).

use super::target::MAX_TARGET_SIZE;
use super::types::{CullMode, DrawState, FrontFace, PixelRect, Triangle, Vertex};

/// Fractional bits of snapped framebuffer coordinates (Vulkan `subPixelPrecisionBits`; lavapipe
/// reports 8).
pub const SUBPIXEL_BITS: u32 = 8;
/// One pixel in snapped (fixed-point) units.
const SUBPIXEL_ONE: i64 = 1 << SUBPIXEL_BITS;
/// Half a pixel in snapped units: the offset of a pixel centre.
const SUBPIXEL_HALF: i64 = SUBPIXEL_ONE / 2;

/// How far, in pixels, the x/y clip planes lie outside the viewport on every side (module docs).
pub const GUARD_BAND_PX: u32 = 1 << 20;

/// Bound on the magnitude of snapped coordinates (module docs, "Exact coverage").
const MAX_ABS_FIXED: i64 = 2 * (GUARD_BAND_PX as i64 + MAX_TARGET_SIZE as i64) * SUBPIXEL_ONE;
const _: () = assert!(
    8 * (MAX_ABS_FIXED as i128) * (MAX_ABS_FIXED as i128) < i64::MAX as i128,
    "edge functions of guard-band coordinates must fit in i64"
);

/// Viewport constants: the transform (module docs, step 2) and the guard-band clip planes.
pub(super) struct Viewport {
    width: u32,
    height: u32,
    half_w: f32,
    half_h: f32,
    /// The x clip planes are `-guard_x·w <= x <= guard_x·w`: `GUARD_BAND_PX` outside the viewport.
    guard_x: f32,
    /// Likewise for y.
    guard_y: f32,
}

impl Viewport {
    pub(super) fn new(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            half_w: width as f32 * 0.5,
            half_h: height as f32 * 0.5,
            guard_x: 1.0 + 2.0 * GUARD_BAND_PX as f32 / width as f32,
            guard_y: 1.0 + 2.0 * GUARD_BAND_PX as f32 / height as f32,
        }
    }

    /// Signed distance-like value of `p` to clip plane `plane`: inside when `>= 0`.
    /// Planes: near `z >= 0`, far `z <= w`, then the guard band's left, right, bottom, top.
    fn plane_distance(&self, plane: usize, p: &[f32; 4]) -> f32 {
        let [x, y, z, w] = *p;
        match plane {
            0 => z,
            1 => w - z,
            2 => self.guard_x * w + x,
            3 => self.guard_x * w - x,
            4 => self.guard_y * w + y,
            5 => self.guard_y * w - y,
            _ => unreachable!("six clip planes"),
        }
    }

    /// Bit mask of the planes `p` is outside of (NaN counts as outside).
    fn outcode(&self, p: &[f32; 4]) -> u32 {
        (0..CLIP_PLANES)
            .filter(|&i| {
                let d = self.plane_distance(i, p);
                d < 0.0 || d.is_nan()
            })
            .fold(0, |m, i| m | 1 << i)
    }
}

const CLIP_PLANES: usize = 6;

/// Clips one triangle to the near, far and guard-band planes (module docs, step 1). Returns the
/// clipped convex polygon, empty when nothing is left.
fn clip_triangle<const N: usize>(tri: &Triangle<N>, viewport: &Viewport) -> Vec<Vertex<N>> {
    let codes = tri.map(|v| viewport.outcode(&v.clip));
    if codes[0] & codes[1] & codes[2] != 0 {
        return Vec::new(); // wholly outside one plane
    }
    let mut poly = tri.to_vec();
    let crossed = codes[0] | codes[1] | codes[2];
    for plane in (0..CLIP_PLANES).filter(|&p| crossed & (1 << p) != 0) {
        let mut out = Vec::with_capacity(poly.len() + 1);
        for (i, cur) in poly.iter().enumerate() {
            let next = &poly[(i + 1) % poly.len()];
            let dc = viewport.plane_distance(plane, &cur.clip);
            let dn = viewport.plane_distance(plane, &next.clip);
            let (cur_in, next_in) = (dc >= 0.0, dn >= 0.0);
            if cur_in {
                out.push(*cur);
            }
            if cur_in != next_in {
                // Always from the inside vertex towards the outside one, so both triangles sharing
                // this edge compute the same point. An inside vertex on the plane is itself the
                // intersection and is emitted on its own.
                let (inside, outside, di, d_out) = if cur_in {
                    (cur, next, dc, dn)
                } else {
                    (next, cur, dn, dc)
                };
                if di > 0.0 {
                    out.push(lerp_vertex(inside, outside, di / (di - d_out)));
                }
            }
        }
        poly = out;
        if poly.len() < 3 {
            return Vec::new();
        }
    }
    poly
}

fn lerp_vertex<const N: usize>(a: &Vertex<N>, b: &Vertex<N>, t: f32) -> Vertex<N> {
    let lerp = |x: f32, y: f32| x + t * (y - x);
    Vertex {
        clip: std::array::from_fn(|i| lerp(a.clip[i], b.clip[i])),
        varyings: std::array::from_fn(|i| lerp(a.varyings[i], b.varyings[i])),
    }
}

/// A vertex after the viewport transform and snapping.
#[derive(Clone, Copy)]
struct ScreenVertex<const N: usize> {
    /// Snapped framebuffer position, in 1/256 pixel.
    pos: [i64; 2],
    /// `z_f = z / w`.
    z: f32,
    /// `1 / w`.
    inv_w: f64,
    varyings: [f32; N],
}

/// `c.round_ties_even()` bit for bit (signed zeros, NaN, infinities) without libm's `rintf`,
/// which is what it compiles to on x86-64's baseline (0.8 % of a `stress` frame, issue 14 round
/// 3). A value of magnitude at least `2^23`, a NaN or an infinity is already integral and returned
/// as it is. Otherwise `|c| + 2^23` lies in `[2^23, 2^24)`, where the `f32` spacing is 1, so the
/// addition rounds `|c|` to an integer with the IEEE default (ties to even; `2^23` is even, so
/// the sum's parity is the result's) and subtracting `2^23` again is exact; the sign is `c`'s,
/// as `round_ties_even` keeps it (`-0.3` gives `-0.0`). Checked against the standard library by
/// `rounding_helpers_equal_the_standard_library`.
#[inline]
pub(crate) fn round_ties_even_exact(c: f32) -> f32 {
    const TWO_23: f32 = 8_388_608.0;
    let a = c.abs();
    if a.is_nan() || a >= TWO_23 {
        return c;
    }
    ((a + TWO_23) - TWO_23).copysign(c)
}

/// `c.round()` (halves away from zero) bit for bit without libm's `roundf` (1.3 % of a
/// 1280x720 frame, called twice per tree fragment by `draw::TreeShader`). A value of magnitude
/// at least `2^23`, a NaN or an infinity is integral; otherwise truncation through `i32` is exact,
/// so is the fraction `|c| - trunc(|c|)` (in `[0, 1)`, with `c`'s exponent or less), and the
/// result moves up by one exactly when that fraction is at least a half; the sign is `c`'s.
/// Checked by `rounding_helpers_equal_the_standard_library`.
#[inline]
pub(crate) fn round_exact(c: f32) -> f32 {
    let a = c.abs();
    if a.is_nan() || a >= 8_388_608.0 {
        return c;
    }
    let t = a as i32 as f32;
    let r = if a - t >= 0.5 { t + 1.0 } else { t };
    r.copysign(c)
}

fn project<const N: usize>(v: &Vertex<N>, viewport: &Viewport) -> Option<ScreenVertex<N>> {
    let [x, y, z, w] = v.clip;
    // Viewport transform in f32 (module docs, step 2), then snapping (step 3).
    let xf = (x / w) * viewport.half_w + viewport.half_w;
    let yf = viewport.half_h - (y / w) * viewport.half_h;
    let snap = |c: f32| {
        let s = round_ties_even_exact(c * SUBPIXEL_ONE as f32);
        (s.is_finite() && s.abs() <= MAX_ABS_FIXED as f32).then_some(s as i64)
    };
    Some(ScreenVertex {
        pos: [snap(xf)?, snap(yf)?],
        z: z / w,
        inv_w: 1.0 / w as f64,
        varyings: v.varyings,
    })
}

/// A triangle ready for coverage: snapped, oriented with positive area, with its edge rules.
#[derive(Clone, Copy)]
pub(super) struct SetupTriangle<const N: usize> {
    pub(super) primitive_id: u32,
    pub(super) front_facing: bool,
    /// Vertices, ordered so that `area > 0` (clockwise on screen, where y points down).
    v: [ScreenVertex<N>; 3],
    /// Twice the signed area in snapped units², `> 0`.
    area: i64,
    /// Per edge (edge `i` is opposite vertex `i`): 0 for a top or left edge, -1 otherwise; a sample
    /// is covered when `E_i + bias_i >= 0` for all `i`.
    pub(super) bias: [i64; 3],
    /// Pixels whose centres lie in the vertices' bounding box, within the target; `None` if none.
    pub(super) bbox: Option<PixelRect>,
    /// A lower bound of [`SetupTriangle::depth`] at every sample the triangle covers
    /// ([`depth_lower_bound`]).
    pub(super) min_depth: f32,
}

/// Twice the signed area of `(a, b, p)`: the edge function of edge `a -> b` at `p`.
fn edge_function(a: [i64; 2], b: [i64; 2], p: [i64; 2]) -> i64 {
    (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
}

/// Whether the edge `a -> b` of a triangle with positive area (y down) is a top or left edge.
///
/// With positive area the interior lies where the edge function is positive. A horizontal edge
/// (`dy == 0`) has the interior below it exactly when `dx > 0`: a top edge. A non-horizontal edge
/// has the interior to its right exactly when `dy < 0`: a left edge.
fn is_top_left(a: [i64; 2], b: [i64; 2]) -> bool {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    dy < 0 || (dy == 0 && dx > 0)
}

/// What [`setup_primitive`] did with one submitted triangle (its [`DrawStats`] shares).
#[derive(Clone, Copy, Default)]
pub(super) struct SetupCounts {
    /// Triangles that left the clipper.
    pub(super) clipped: u64,
    /// Of those, triangles with non-zero snapped area that were not culled.
    pub(super) rasterized: u64,
}

/// Clips, projects and sets up one submitted triangle, appending to `out` the pieces that survive
/// setup **and cover at least one pixel centre of the target** (a piece with no pixel in its box
/// can produce no fragment, so it is counted in [`SetupCounts::rasterized`] but not kept: that is
/// most of a far forest's triangles).
///
/// Speed-up (issue 14): a triangle inside every clip plane (the common case) skips the clipper's
/// polygon and is projected and set up directly, with no allocation; it is exactly what the clipper
/// would return (the polygon of a triangle that crosses no plane is the triangle itself).
pub(super) fn setup_primitive<const N: usize>(
    id: u32,
    tri: &Triangle<N>,
    viewport: &Viewport,
    state: &DrawState,
    out: &mut Vec<SetupTriangle<N>>,
) -> SetupCounts {
    let mut counts = SetupCounts::default();
    if tri.iter().any(|v| v.clip.iter().any(|c| !c.is_finite())) {
        return counts;
    }
    let mut keep = |t: Option<SetupTriangle<N>>| {
        if let Some(t) = t {
            counts.rasterized += 1;
            if t.bbox.is_some() {
                out.push(t);
            }
        }
    };
    if tri.iter().all(|v| viewport.outcode(&v.clip) == 0) {
        counts.clipped = 1;
        let [a, b, c] = tri;
        if let (Some(a), Some(b), Some(c)) = (
            project(a, viewport),
            project(b, viewport),
            project(c, viewport),
        ) {
            keep(setup_triangle(id, [a, b, c], viewport, state));
        }
        return counts;
    }
    let poly = clip_triangle(tri, viewport);
    if poly.is_empty() {
        return counts;
    }
    counts.clipped = poly.len() as u64 - 2;
    let Some(screen) = poly
        .iter()
        .map(|v| project(v, viewport))
        .collect::<Option<Vec<_>>>()
    else {
        return counts;
    };
    for i in 1..screen.len() - 1 {
        keep(setup_triangle(
            id,
            [screen[0], screen[i], screen[i + 1]],
            viewport,
            state,
        ));
    }
    counts
}

fn setup_triangle<const N: usize>(
    primitive_id: u32,
    mut v: [ScreenVertex<N>; 3],
    viewport: &Viewport,
    state: &DrawState,
) -> Option<SetupTriangle<N>> {
    let mut area = edge_function(v[0].pos, v[1].pos, v[2].pos);
    if area == 0 {
        return None; // degenerate: covers nothing
    }
    // Vulkan's `a = -area / 2` (its formula's minus sign turns y-down into y-up): `a > 0` is
    // counter-clockwise as seen in NDC with y up.
    let ccw = area < 0;
    let front_facing = match state.front_face {
        FrontFace::Ccw => ccw,
        FrontFace::Cw => !ccw,
    };
    let culled = match state.cull {
        CullMode::None => false,
        CullMode::Front => front_facing,
        CullMode::Back => !front_facing,
    };
    if culled {
        return None;
    }
    if area < 0 {
        v.swap(1, 2);
        area = -area;
    }
    let p = v.map(|s| s.pos);
    // Edge i runs between the two vertices other than i, in winding order.
    let bias = std::array::from_fn(|i| {
        let (a, b) = (p[(i + 1) % 3], p[(i + 2) % 3]);
        if is_top_left(a, b) { 0 } else { -1 }
    });

    // Pixels whose centre X = 256·x + 128 lies within [min, max] of the vertices.
    let min = |k: usize| p.iter().map(|q| q[k]).min().unwrap_or(0);
    let max = |k: usize| p.iter().map(|q| q[k]).max().unwrap_or(0);
    let first = |lo: i64| -((SUBPIXEL_HALF - lo).div_euclid(SUBPIXEL_ONE)); // ceil((lo - 128) / 256)
    let last = |hi: i64| (hi - SUBPIXEL_HALF).div_euclid(SUBPIXEL_ONE); // floor((hi - 128) / 256)
    let x0 = first(min(0)).max(0);
    let y0 = first(min(1)).max(0);
    let x1 = (last(max(0)) + 1).min(viewport.width as i64);
    let y1 = (last(max(1)) + 1).min(viewport.height as i64);
    let bbox = (x0 < x1 && y0 < y1).then_some(PixelRect {
        x0: x0 as u32,
        y0: y0 as u32,
        x1: x1 as u32,
        y1: y1 as u32,
    });

    let min_depth = depth_lower_bound([v[0].z, v[1].z, v[2].z]);
    Some(SetupTriangle {
        primitive_id,
        front_facing,
        v,
        area,
        bias,
        bbox,
        min_depth,
    })
}

/// A lower bound of the depth ([`SetupTriangle::depth`]) at every sample a triangle with vertex
/// depths `z` covers, for the early depth test's shortcut (module docs, "Depth bound"): `0` when
/// a vertex depth is at most 0 (the depth is clamped to `[0, 1]`), `-∞` (no bound) when one is
/// NaN, otherwise `zmin · (1 - 2^-50)` rounded to `f32` and clamped.
///
/// Why it is a bound: at a covered sample every edge function is `>= 0` (the coverage test is
/// `E_i + bias_i >= 0` with `bias_i <= 0`), so the barycentrics `b_i = E_i / area` are `>= 0` and
/// sum to 1 in exact arithmetic (`E_0 + E_1 + E_2 = area`). Each computed `b_i` is within a factor
/// `(1 ± u)` of the exact one (`u = 2^-53`), and the depth's two products and two sums add three
/// more such factors, all of non-negative terms: the `f64` depth is at least
/// `zmin · (1 - u)^4 >= zmin · (1 - 4u)`, which `zmin · (1 - 2^-50)` (at most `zmin · (1 - 7u)`
/// after its own rounding) does not exceed. Rounding to `f32` and clamping are non-decreasing, so
/// the bound survives them.
fn depth_lower_bound(z: [f32; 3]) -> f32 {
    if z.iter().any(|z| z.is_nan()) {
        return f32::NEG_INFINITY;
    }
    let zmin = z[0].min(z[1]).min(z[2]);
    if zmin <= 0.0 {
        return 0.0;
    }
    ((zmin as f64 * (1.0 - DEPTH_BOUND_MARGIN)) as f32).clamp(0.0, 1.0)
}

/// The relative margin of [`depth_lower_bound`]: `2^-50`, above the `4 · 2^-53` that the `f64`
/// depth's five roundings can take off the smallest vertex depth.
const DEPTH_BOUND_MARGIN: f64 = 1.0 / (1u64 << 50) as f64;

impl<const N: usize> SetupTriangle<N> {
    /// Edge functions at the centre of pixel `(x, y)`; `E_i` belongs to the edge opposite vertex
    /// `i`, so `E_i / area` is vertex `i`'s screen-space barycentric weight.
    pub(super) fn edges(&self, x: u32, y: u32) -> [i64; 3] {
        let s = [
            x as i64 * SUBPIXEL_ONE + SUBPIXEL_HALF,
            y as i64 * SUBPIXEL_ONE + SUBPIXEL_HALF,
        ];
        let p = [self.v[0].pos, self.v[1].pos, self.v[2].pos];
        [
            edge_function(p[1], p[2], s),
            edge_function(p[2], p[0], s),
            edge_function(p[0], p[1], s),
        ]
    }

    /// The edge functions at the four pixel centres of the 2x2 quad at `(qx, qy)`, in [`QUAD`]
    /// order: those of the top-left pixel plus the exact integer steps of one pixel right and one
    /// down (an edge function is linear in the sample position), so each value equals
    /// [`SetupTriangle::edges`] at that pixel bit for bit, for a quarter of the multiplications.
    #[cfg(test)]
    fn quad_edges(&self, qx: u32, qy: u32) -> [[i64; 3]; 4] {
        quad_edges(self.edges(qx, qy), &self.edge_steps())
    }

    /// How the edge functions change one pixel right (`[0]`) and one pixel down (`[1]`): exact
    /// integers, since an edge function is linear in the sample position.
    pub(super) fn edge_steps(&self) -> [[i64; 3]; 2] {
        let p = self.v.map(|v| v.pos);
        // Edge i runs from a = p[i+1] to b = p[i+2]: E = (b.x - a.x)(s.y - a.y) - (b.y - a.y)(s.x - a.x).
        [
            std::array::from_fn(|i| -(p[(i + 2) % 3][1] - p[(i + 1) % 3][1]) * SUBPIXEL_ONE),
            std::array::from_fn(|i| (p[(i + 2) % 3][0] - p[(i + 1) % 3][0]) * SUBPIXEL_ONE),
        ]
    }

    /// The top-left coverage test (module docs, step 5): `E_i + bias_i >= 0` for all three
    /// edges, written as one sign test of their bitwise OR (negative exactly when one of them
    /// is), which compiles without branches.
    #[inline]
    pub(super) fn covers(&self, e: &[i64; 3]) -> bool {
        ((e[0] + self.bias[0]) | (e[1] + self.bias[1]) | (e[2] + self.bias[2])) >= 0
    }

    /// Screen-space barycentric weights of a sample with edge functions `e`.
    #[inline]
    pub(super) fn barycentrics(&self, e: &[i64; 3]) -> [f64; 3] {
        let area = self.area as f64;
        [e[0] as f64 / area, e[1] as f64 / area, e[2] as f64 / area]
    }

    /// Depth at a sample with barycentrics `b` ([`SetupTriangle::barycentrics`]): linear in
    /// screen space, clamped to `[0, 1]`.
    ///
    /// The sums here and in [`SetupTriangle::varyings`] are written out left to right (they were
    /// `Iterator::sum`, whose fold starts at `-0.0`, and `-0.0 + x = x`: the same value bit for
    /// bit, without the iterator and `array::from_fn` overhead, issue 14).
    #[inline]
    pub(super) fn depth(&self, b: &[f64; 3]) -> f32 {
        let v = &self.v;
        let z = b[0] * v[0].z as f64 + b[1] * v[1].z as f64 + b[2] * v[2].z as f64;
        (z as f32).clamp(0.0, 1.0)
    }

    /// Perspective-correct varyings at a sample with barycentrics `b` (inside the triangle or,
    /// for helper pixels, outside it).
    #[inline]
    pub(super) fn varyings(&self, b: &[f64; 3]) -> [f32; N] {
        let v = &self.v;
        let q = [b[0] * v[0].inv_w, b[1] * v[1].inv_w, b[2] * v[2].inv_w];
        let denom = q[0] + q[1] + q[2];
        let mut out = [0.0f32; N];
        for (j, o) in out.iter_mut().enumerate() {
            let num = q[0] * v[0].varyings[j] as f64
                + q[1] * v[1].varyings[j] as f64
                + q[2] * v[2].varyings[j] as f64;
            *o = (num / denom) as f32;
        }
        out
    }
}

/// Pixel offsets within a quad: top-left, top-right, bottom-left, bottom-right.
pub(super) const QUAD: [(u32, u32); 4] = [(0, 0), (1, 0), (0, 1), (1, 1)];

/// The edge functions at the four pixel centres of a quad, in [`QUAD`] order, from those `e` of
/// its top-left pixel and the steps of [`SetupTriangle::edge_steps`]: each equals
/// [`SetupTriangle::edges`] at that pixel bit for bit (integer arithmetic), for no
/// multiplication. (Written out element by element: `std::array::from_fn` over `[i64; 3]`
/// compiled to stack copies that were 18 % of a 1280x720 frame, issue 14.)
#[inline]
pub(super) fn quad_edges(e: [i64; 3], steps: &[[i64; 3]; 2]) -> [[i64; 3]; 4] {
    let [sx, sy] = steps;
    let right = add3(e, *sx);
    [e, right, add3(e, *sy), add3(right, *sy)]
}

/// `a + b` element by element.
#[inline(always)]
pub(super) fn add3(a: [i64; 3], b: [i64; 3]) -> [i64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// `a · k` element by element.
#[inline(always)]
pub(super) fn mul3(a: [i64; 3], k: i64) -> [i64; 3] {
    [a[0] * k, a[1] * k, a[2] * k]
}

/// The quads `m0..m1` (counted from the row's first, `0..row_quads`) of one row of quads that
/// may hold a pixel `tri` covers, from the edge functions `row` at the row's first quad's
/// top-left pixel and the per-pixel `steps`; `None` when none may. Exact (issue 14, session
/// 10): an edge function is linear, so its largest value over a quad's four pixel centres is
/// `E + max(sx, 0) + max(sy, 0)` at the quad's top-left pixel, an exact integer, and a quad
/// where that value plus the edge's bias is negative for some edge covers none of its pixels;
/// along the row that bound is `A + m·2sx`, so the quads it allows form one interval per edge,
/// found by exact integer division. Every skipped quad is one the walk would have left at its
/// coverage test with nothing counted or written. (Every value is an edge function at a real
/// pixel centre or a quad index times a step of at most a tile's width, so within the bounds of
/// "Exact coverage".)
#[inline]
pub(super) fn covered_quad_span<const N: usize>(
    tri: &SetupTriangle<N>,
    row: [i64; 3],
    steps: &[[i64; 3]; 2],
    row_quads: u32,
) -> Option<(u32, u32)> {
    let (mut lo, mut hi) = (0i64, row_quads as i64);
    for i in 0..3 {
        let (sx, sy) = (steps[0][i], steps[1][i]);
        let a = row[i] + sx.max(0) + sy.max(0) + tri.bias[i];
        let s = 2 * sx;
        if s > 0 {
            if a < 0 {
                // The first m with a + m·s >= 0: ceil(-a / s).
                lo = lo.max((-a + s - 1) / s);
            }
        } else if a < 0 {
            return None; // the bound only falls (or stays) along the row
        } else if s < 0 {
            // The last m with a + m·s >= 0 is floor(a / -s); the range ends after it.
            hi = hi.min(a / -s + 1);
        }
    }
    (lo < hi).then_some((lo as u32, hi as u32))
}

#[cfg(test)]
mod tests {
    use super::super::target::TILE_SIZE;
    use super::super::test_util::unit_random;
    use super::*;

    fn vertex(x: f32, y: f32) -> Vertex<0> {
        Vertex::new([x, y, 0.5, 1.0], [])
    }

    #[test]
    fn top_left_classification_of_a_clockwise_triangle() {
        // (0,0) -> (4,0) -> (0,4) in y-down pixels has positive area: top edge, hypotenuse
        // (bottom-right, not top-left), left edge.
        let p = [[0, 0], [4, 0], [0, 4]];
        assert!(edge_function(p[0], p[1], p[2]) > 0);
        assert!(is_top_left(p[0], p[1]));
        assert!(!is_top_left(p[1], p[2]));
        assert!(is_top_left(p[2], p[0]));
        // A bottom edge is not top-left.
        assert!(!is_top_left([4, 4], [0, 4]));
    }

    #[test]
    fn the_clipper_keeps_inside_triangles_untouched_and_drops_outside_ones() {
        let vp = Viewport::new(16, 16);
        let inside = [vertex(-0.5, -0.5), vertex(0.5, -0.5), vertex(0.0, 0.5)];
        assert_eq!(clip_triangle(&inside, &vp), inside.to_vec());
        let behind = inside.map(|v| Vertex::new([v.clip[0], v.clip[1], -0.1, 1.0], []));
        assert!(clip_triangle(&behind, &vp).is_empty());
        let beyond = inside.map(|v| Vertex::new([v.clip[0], v.clip[1], 1.5, 1.0], []));
        assert!(clip_triangle(&beyond, &vp).is_empty());
    }

    #[test]
    fn the_clipper_cuts_at_the_near_plane_and_keeps_the_polygon_convex() {
        let vp = Viewport::new(16, 16);
        let tri = [
            Vertex::new([0.0, 0.0, -1.0, 1.0], [0.0]),
            Vertex::new([0.5, 0.0, 1.0, 2.0], [1.0]),
            Vertex::new([0.0, 0.5, 1.0, 2.0], [1.0]),
        ];
        let poly = clip_triangle(&tri, &vp);
        assert_eq!(poly.len(), 4);
        for v in &poly {
            assert!(v.clip[2] >= 0.0 && v.clip[2] <= v.clip[3], "{v:?}");
        }
        // The cut points are halfway along the edges from the clipped vertex (z: -1 -> 1).
        assert!(poly.iter().any(|v| v.varyings == [0.5]));
    }

    #[test]
    fn a_shared_edge_is_cut_at_the_same_point_from_both_sides() {
        let vp = Viewport::new(16, 16);
        let a = Vertex::new([0.3, -0.7, -0.37, 1.3], [0.1]);
        let b = Vertex::new([-0.2, 0.9, 0.81, 1.1], [0.7]);
        let c = Vertex::new([0.9, 0.4, 0.5, 1.0], [0.3]);
        let d = Vertex::new([-0.9, -0.4, 0.5, 1.0], [0.9]);
        let p1 = clip_triangle(&[a, b, c], &vp);
        let p2 = clip_triangle(&[b, a, d], &vp);
        let new1: Vec<_> = p1.iter().filter(|v| ![a, b, c].contains(v)).collect();
        let new2: Vec<_> = p2.iter().filter(|v| ![a, b, d].contains(v)).collect();
        let common: Vec<_> = new1.iter().filter(|v| new2.contains(v)).collect();
        assert_eq!(common.len(), 1, "{p1:?}\n{p2:?}");
        assert!(common[0].clip[2].abs() < 1e-6);
    }

    /// `quad_edges` (incremental) equals `edges` evaluated at each of the quad's pixels, for
    /// triangles of every size up to the guard band, both windings.
    /// `round_ties_even_exact` and `round_exact` equal `f32::round_ties_even` and `f32::round`
    /// bit for bit: at the special values, at every half-integer below `2^23` and its two
    /// neighbours (the ties and the values either side) for a sample of them, and on a dense
    /// sample of bit patterns of both signs (every 997th).
    #[test]
    fn rounding_helpers_equal_the_standard_library() {
        let mut checked = 0u64;
        let mut check = |c: f32| {
            for c in [c, -c] {
                assert_eq!(
                    round_ties_even_exact(c).to_bits(),
                    c.round_ties_even().to_bits(),
                    "round_ties_even({c:e})"
                );
                assert_eq!(
                    round_exact(c).to_bits(),
                    c.round().to_bits(),
                    "round({c:e})"
                );
                checked += 1;
            }
        };
        for c in [
            0.0,
            0.5,
            1.5,
            2.5,
            0.49999997,
            f32::MIN_POSITIVE,
            1e-45,
            8_388_607.5,
            8_388_608.0,
            16_777_217.0,
            f32::MAX,
            f32::INFINITY,
            f32::NAN,
        ] {
            check(c);
        }
        for i in (0..(1u32 << 23)).step_by(101) {
            let half = i as f32 + 0.5;
            check(half);
            check(f32::from_bits(half.to_bits() - 1));
            check(f32::from_bits(half.to_bits() + 1));
        }
        for bits in (0..0x7f80_0000u32).step_by(997) {
            check(f32::from_bits(bits));
        }
        assert!(checked > 4_000_000, "{checked}");
    }

    /// A varying with the same value at every vertex (the draw's tree scale,
    /// `draw::TREE_VARYINGS`) reads back bit for bit at every covered sample: through the
    /// clipper (triangles crossing the near plane and the sides) and the perspective-correct
    /// `f64` interpolation. Planted `(num / denom) as f32` -> `(num as f32) / (denom as f32)`
    /// fails it.
    #[test]
    fn a_constant_varying_interpolates_to_itself() {
        let vp = Viewport::new(64, 48);
        let mut next = unit_random(29);
        let (mut samples, mut clipped) = (0u64, 0u64);
        for case in 0..3000 {
            // Values of every magnitude a scale takes, odd mantissas included.
            let c = f32::from_bits(0x3a00_0000 + (next() * 0x0a00_0000 as f32) as u32);
            let tri = [0, 1, 2].map(|_| {
                let w = if case % 3 == 0 {
                    next() * 4.0 - 1.0
                } else {
                    0.2 + 4.0 * next()
                };
                let (x, y) = (
                    (next() * 3.0 - 1.5) * w.abs(),
                    (next() * 3.0 - 1.5) * w.abs(),
                );
                Vertex::new([x, y, next() * w.abs(), w], [c])
            });
            let mut out = Vec::new();
            let counts = setup_primitive(case, &tri, &vp, &DrawState::OPAQUE, &mut out);
            clipped += u64::from(counts.clipped > 1 || tri.iter().any(|v| v.clip[3] <= 0.0));
            for t in &out {
                let Some(bbox) = t.bbox else { continue };
                for y in bbox.y0..bbox.y1 {
                    for x in bbox.x0..bbox.x1 {
                        let e = t.edges(x, y);
                        if !t.covers(&e) {
                            continue;
                        }
                        let got = t.varyings(&t.barycentrics(&e))[0];
                        assert_eq!(
                            got.to_bits(),
                            c.to_bits(),
                            "case {case}: a constant varying {c:e} read back as {got:e} at ({x}, {y})"
                        );
                        samples += 1;
                    }
                }
            }
        }
        assert!(
            samples > 100_000 && clipped > 500,
            "{samples} samples, {clipped} clipped"
        );
    }

    /// Random set-up triangles of several sizes, depths and perspectives, for the walk's exact
    /// shortcuts below.
    fn random_setup_triangles(seed: u64, cases: usize) -> Vec<SetupTriangle<0>> {
        let vp = Viewport::new(640, 360);
        let mut next = unit_random(seed);
        let mut out = Vec::new();
        for case in 0..cases {
            let scale = [0.01, 0.2, 1.0, 4.0, 4000.0][case % 5];
            let depth_range = [1.0, 1e-3, 0.0][case % 3];
            let base = next();
            let tri = [0, 1, 2].map(|_| {
                let w = [1.0, 0.5 + 4.0 * next()][case % 2];
                let (mut x, mut y) = ((next() * 2.0 - 1.0) * scale, (next() * 2.0 - 1.0) * scale);
                if case % 7 == 0 {
                    // On pixel centres: edge functions land exactly on 0 and on multiples of
                    // their steps, the edge cases of exact integer division.
                    let centre = |c: f32, size: f32| {
                        let px = ((c.clamp(-1.0, 1.0) + 1.0) / 2.0 * size).floor() + 0.5;
                        px / size * 2.0 - 1.0
                    };
                    (x, y) = (centre(x, 640.0), -centre(-y, 360.0));
                }
                let z = (base + depth_range * next()).min(1.0);
                Vertex::new([x * w, y * w, z * w, w], [])
            });
            setup_primitive(case as u32, &tri, &vp, &DrawState::OPAQUE, &mut out);
        }
        out
    }

    #[test]
    fn covered_quad_spans_hold_every_quad_with_a_covered_pixel() {
        let (mut covered_quads, mut skipped) = (0, 0);
        for t in random_setup_triangles(0x51ab_1e5e, 600) {
            let Some(b) = t.bbox else { continue };
            // A window of the box as large as a tile, as `render_tile` walks it.
            let r = PixelRect {
                x1: b.x1.min(b.x0 + TILE_SIZE),
                y1: b.y1.min(b.y0 + TILE_SIZE),
                ..b
            };
            let (qx0, qy0) = (r.x0 & !1, r.y0 & !1);
            let steps = t.edge_steps();
            let row_quads = (r.x1 - qx0).div_ceil(2);
            for qy in (qy0..r.y1).step_by(2) {
                let span = covered_quad_span(&t, t.edges(qx0, qy), &steps, row_quads);
                for m in 0..row_quads {
                    let qx = qx0 + 2 * m;
                    let any = QUAD.iter().any(|&(dx, dy)| {
                        r.contains(qx + dx, qy + dy) && t.covers(&t.edges(qx + dx, qy + dy))
                    });
                    let inside = span.is_some_and(|(m0, m1)| (m0..m1).contains(&m));
                    assert!(
                        !any || inside,
                        "quad ({qx}, {qy}) covers a pixel, span {span:?}"
                    );
                    covered_quads += u32::from(any);
                    skipped += u32::from(!inside);
                }
            }
        }
        assert!(
            covered_quads > 2_000,
            "only {covered_quads} covered quads checked"
        );
        assert!(skipped > 2_000, "the spans skipped only {skipped} quads");
    }

    #[test]
    fn the_depth_bound_is_at_most_every_covered_depth() {
        let (mut checked, mut equal) = (0, 0);
        for t in random_setup_triangles(0xde97_4b0d, 600) {
            let Some(b) = t.bbox else { continue };
            for y in b.y0..b.y1.min(b.y0 + 48) {
                for x in b.x0..b.x1.min(b.x0 + 48) {
                    let e = t.edges(x, y);
                    if !t.covers(&e) {
                        continue;
                    }
                    let depth = t.depth(&t.barycentrics(&e));
                    assert!(
                        t.min_depth <= depth,
                        "pixel ({x}, {y}): depth {depth} below the bound {}",
                        t.min_depth
                    );
                    checked += 1;
                    equal += u32::from(t.min_depth == depth);
                }
            }
        }
        assert!(checked > 20_000, "only {checked} covered pixels checked");
        // Flat triangles reach their bound: it is not a loose one.
        assert!(
            equal > 1_000,
            "the bound was reached at only {equal} pixels"
        );
    }

    #[test]
    fn quad_edges_equal_the_edge_functions_at_each_pixel() {
        let vp = Viewport::new(640, 360);
        let mut seed = 0x9e37_79b9_7f4a_7c15_u64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f32 / (1u64 << 53) as f32
        };
        let mut checked = 0;
        for case in 0..400 {
            let scale = [1.0, 4.0, 4000.0][case % 3];
            let tri = [0, 1, 2]
                .map(|_| vertex((next() * 2.0 - 1.0) * scale, (next() * 2.0 - 1.0) * scale));
            let mut pieces = Vec::new();
            setup_primitive(case as u32, &tri, &vp, &DrawState::OPAQUE, &mut pieces);
            for t in &pieces {
                let Some(b) = t.bbox else { continue };
                for qy in ((b.y0 & !1)..b.y1.min(b.y0 + 40)).step_by(2) {
                    for qx in ((b.x0 & !1)..b.x1.min(b.x0 + 40)).step_by(2) {
                        let quad = t.quad_edges(qx, qy);
                        for (k, (dx, dy)) in QUAD.iter().enumerate() {
                            assert_eq!(quad[k], t.edges(qx + dx, qy + dy), "case {case}");
                            checked += 1;
                        }
                    }
                }
            }
        }
        assert!(checked > 10_000, "only {checked} pixels checked");
    }
}

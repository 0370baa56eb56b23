//! Celba's point LOD (issue 33 item 1; `forestlod_shared::points`, `reference::points`), on
//! random meshes (random triangles, blocky random alpha textures, `uv` past the edges) and the
//! five built-in species:
//! - records are sorted by area ascending, with consistent parent links and cut keys;
//! - a union's area lies between its largest part and the parts' sum, the exact union equals a
//!   brute-force oracle and is at most the seed's hull, equal when every square's z-extent shares
//!   a point; a merged record's area lies between its largest child and its children's sum;
//! - Alg. 5's groups hold at most `max_group` placed points;
//! - no placed point lies on a transparent texel;
//! - cut mode represents every placed point exactly once at every depth (interval mode's holes
//!   and doubles are counted and printed, not asserted);
//! - a batch's range holds every one of its trees' drawn records;
//! - beyond the safe change distance every dropped primitive is below its screen threshold;
//! - the union is taken on the XZ plane (slip (b)): a tree built in the seed's Y-up frame and
//!   rotated into ours keeps its areas;
//! - the build is deterministic and independent of the thread count.

use std::sync::OnceLock;

use forestlod_reference::points::{
    MeshPoints, PlacedPoint, PointThresholds, batch_range, build_hierarchy, build_mesh_points,
    build_points, holes_and_doubles, mesh_change_distance, range_records, representation_counts,
    select_tree, select_tree_lod, texel_at, uv_at,
};
use forestlod_reference::scene::TreeMesh;
use forestlod_reference::scene::builtin::species_meshes;
use forestlod_reference::texture::Image;
use forestlod_shared::points::{
    DetailPreset, NO_PARENT, PointParams, PointSelect, UnionMode, klee_area, point_hash,
    seed_hull_area, square_xz, texel_opaque,
};
use forestlod_tests::property_config;
use proptest::prelude::*;

/// Relative slack for comparing areas computed along different `f64` paths (a sweep sums strips
/// in another order than a brute-force grid) and stored as `f32` (a record's area is rounded
/// once, 2^-24 relative): 1e-5 is far below any real overlap and far above both roundings.
const AREA_REL_TOL: f64 = 1e-5;

/// Relative slack for the change-distance property: `D_c` is an `f64` square root, and the test
/// evaluates `C·A/d²` at `d` a little beyond it; only rounding can exceed the threshold.
const CHANGE_REL_TOL: f64 = 1e-9;

/// The built-in species meshes, built once.
fn species() -> &'static [TreeMesh] {
    static MESHES: OnceLock<Vec<TreeMesh>> = OnceLock::new();
    MESHES.get_or_init(species_meshes)
}

/// A random mesh (module docs): `ntri` triangles, a `side`² texture whose 4x4 blocks are opaque
/// with probability `density`, `uv` in `[-0.1, 1.1]`.
fn random_mesh(seed: u32, ntri: u32, side: u32, density: f32) -> TreeMesh {
    let h = |a: u32, b: u32| point_hash(seed, a, b, 7) as f32 / u32::MAX as f32;
    let texture = Image::from_fn(side, side, |x, y| {
        let opaque = h(1000 + x / 4, y / 4) < density;
        let c = (h(x, y + 5000) * 255.0) as u8;
        [
            c,
            255 - c,
            (x * 7) as u8,
            if opaque { 255 } else { (h(x, y) * 100.0) as u8 },
        ]
    });
    let mut mesh = TreeMesh::new("random", texture);
    for t in 0..ntri {
        for k in 0..3 {
            let i = 3 * t + k;
            mesh.positions
                .push([h(i, 1) * 6.0 - 3.0, h(i, 2) * 6.0 - 3.0, h(i, 3) * 10.0]);
            mesh.uvs.push([h(i, 4) * 1.2 - 0.1, h(i, 5) * 1.2 - 0.1]);
            mesh.indices.push(i);
        }
    }
    mesh
}

/// A mesh: a species (`which < 5`) or a random one.
fn mesh_strategy() -> impl Strategy<Value = TreeMesh> {
    (
        0u32..10,
        any::<u32>(),
        1u32..8,
        prop::sample::select(vec![8u32, 16, 32]),
        0.05f32..1.0,
    )
        .prop_map(|(which, seed, ntri, side, density)| {
            if which < 5 {
                species()[which as usize].clone()
            } else {
                random_mesh(seed, ntri, side, density)
            }
        })
}

fn params_strategy() -> impl Strategy<Value = PointParams> {
    (
        1u32..400,
        1u32..12,
        (1u32..4, 1u32..4, 1u32..4),
        prop::sample::select(UnionMode::ALL.to_vec()),
        0u32..12,
        0.0f32..1.0,
        0.0f32..1.0,
    )
        .prop_map(
            |(n_pts, max_group, (gx, gy, gz), union, retries, uplift, cut)| PointParams {
                n_pts,
                max_group,
                grid: [gx, gy, gz],
                union,
                retries,
                uplift,
                triangle_cutoff: cut,
                ..PointParams::default()
            },
        )
}

fn build(mesh: &TreeMesh, params: &PointParams) -> MeshPoints {
    build_mesh_points(mesh, params).expect("valid params")
}

/// The metric constant of a 1280x720 frame at 60° (`f_px²`), or a random multiple of it.
fn metric_c(factor: f64) -> f64 {
    let f = 720.0 / (2.0 * (30.0f64).to_radians().tan());
    f * f * factor
}

/// Brute-force union area: coordinate compression, every elementary cell tested (`O(n³)`).
fn brute_union(rects: &[[f64; 4]]) -> f64 {
    let mut xs: Vec<f64> = rects.iter().flat_map(|r| [r[0], r[2]]).collect();
    let mut ys: Vec<f64> = rects.iter().flat_map(|r| [r[1], r[3]]).collect();
    xs.sort_by(f64::total_cmp);
    ys.sort_by(f64::total_cmp);
    xs.dedup();
    ys.dedup();
    let mut area = 0.0;
    for i in 0..xs.len().saturating_sub(1) {
        for j in 0..ys.len().saturating_sub(1) {
            let (cx, cy) = (0.5 * (xs[i] + xs[i + 1]), 0.5 * (ys[j] + ys[j + 1]));
            if rects
                .iter()
                .any(|r| r[0] <= cx && cx <= r[2] && r[1] <= cy && cy <= r[3])
            {
                area += (xs[i + 1] - xs[i]) * (ys[j + 1] - ys[j]);
            }
        }
    }
    area
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= AREA_REL_TOL * a.abs().max(b.abs()).max(1e-12)
}

fn squares_strategy() -> impl Strategy<Value = Vec<[f64; 4]>> {
    prop::collection::vec((-5.0f64..5.0, -5.0f64..5.0, 0.01f64..4.0), 1..40).prop_map(|v| {
        v.into_iter()
            .map(|(x, z, s)| [x - s / 2.0, z - s / 2.0, x + s / 2.0, z + s / 2.0])
            .collect()
    })
}

proptest! {
    #![proptest_config(property_config())]

    /// Areas ascending, parents and cut keys consistent. Caught: the area sort dropped
    /// (records in creation order: merged points after their children but placed points of
    /// different triangles out of order) fails "ascending".
    #[test]
    fn point_areas_are_ascending(mesh in mesh_strategy(), params in params_strategy()) {
        let set = build(&mesh, &params);
        for w in set.records.windows(2) {
            prop_assert!(w[0].area <= w[1].area, "{} > {}", w[0].area, w[1].area);
        }
        for (i, r) in set.records.iter().enumerate() {
            if r.parent != NO_PARENT {
                let p = &set.records[r.parent as usize];
                prop_assert_eq!(r.parent_area, p.area);
                prop_assert!(set.children[r.parent as usize].contains(&(i as u32)));
                prop_assert!(r.area <= p.area, "child {} > parent {}", r.area, p.area);
            }
        }
        for w in set.cut_keys.windows(2) {
            prop_assert!(w[0] <= w[1]);
        }
    }

    /// A union between its largest part and the parts' sum; exact = brute force ≤ hull; equal
    /// when every z-extent holds a common z. Caught: `UnionMode::Exact` computed by the hull
    /// sweep (the design's "hull used where exact is claimed") fails the brute-force oracle.
    #[test]
    fn union_areas_are_bounded(rects in squares_strategy(), split in 0usize..40, common in any::<bool>()) {
        let mut rects = rects;
        if common {
            // Every square's z-extent contains z = 0.
            for r in rects.iter_mut() {
                let (c, h) = (0.5 * (r[1] + r[3]), 0.5 * (r[3] - r[1]));
                let c = c.clamp(-0.99 * h, 0.99 * h);
                r[1] = c - h;
                r[3] = c + h;
            }
        }
        let exact = klee_area(&rects);
        let brute = brute_union(&rects);
        prop_assert!(close(exact, brute), "klee {exact} vs brute {brute}");
        let hull = seed_hull_area(&rects);
        prop_assert!(exact <= hull * (1.0 + AREA_REL_TOL), "exact {exact} > hull {hull}");
        if common {
            prop_assert!(close(exact, hull), "common z: exact {exact} vs hull {hull}");
        }
        let k = split % rects.len();
        if k > 0 {
            let (a, b) = (klee_area(&rects[..k]), klee_area(&rects[k..]));
            prop_assert!(exact >= a.max(b) * (1.0 - AREA_REL_TOL), "{exact} < max({a}, {b})");
            prop_assert!(exact <= (a + b) * (1.0 + AREA_REL_TOL), "{exact} > {a} + {b}");
        }
    }

    /// A merged record's area (exact union) lies between its largest child and its children's
    /// sum, and is the exact union of the squares below it. Caught: a merged area taken as the
    /// area of the squares' bounding box exceeds the children's sum.
    #[test]
    fn merged_areas_lie_between_largest_child_and_sum(mesh in mesh_strategy(), params in params_strategy()) {
        let params = PointParams { union: UnionMode::Exact, ..params };
        let set = build(&mesh, &params);
        let mut worst = 0.0f64;
        for (i, r) in set.records.iter().enumerate() {
            let ch = &set.children[i];
            if ch.is_empty() {
                continue;
            }
            let areas: Vec<f64> = ch.iter().map(|&c| set.records[c as usize].area as f64).collect();
            let sum: f64 = areas.iter().sum();
            let max = areas.iter().copied().fold(0.0, f64::max);
            let a = r.area as f64;
            prop_assert!(a >= max, "record {i}: {a} < largest child {max}");
            prop_assert!(a <= sum * (1.0 + AREA_REL_TOL), "record {i}: {a} > sum {sum}");
            let squares: Vec<[f64; 4]> = set
                .leaves_below(i as u32)
                .iter()
                .map(|&l| square_xz(set.records[l as usize].pos, set.records[l as usize].area))
                .collect();
            let exact = klee_area(&squares).max(max);
            worst = worst.max((a - exact).abs() / exact.max(1e-12));
            prop_assert!(close(a, exact), "record {i}: {a} vs union {exact}");
        }
        if worst > 1e-7 {
            eprintln!("merged areas: worst relative difference to the recomputed union {worst:.2e}");
        }
    }

    /// Alg. 5: groups hold at most `max_group` placed points and cover them all; a record with
    /// placed children is a group, any other merged record is a binary split. Caught: the stop
    /// test `len <= 2·max_group` leaves groups twice too large.
    #[test]
    fn alg5_groups_hold_at_most_max_group(mesh in mesh_strategy(), params in params_strategy()) {
        let set = build(&mesh, &params);
        let placed = set.placed().count();
        prop_assert_eq!(set.groups.iter().map(|&g| g as usize).sum::<usize>(), placed);
        for &g in &set.groups {
            prop_assert!(g >= 1 && g <= params.max_group, "group of {g} > {}", params.max_group);
        }
        for ch in &set.children {
            if ch.is_empty() {
                continue;
            }
            let leaves = ch.iter().filter(|&&c| set.children[c as usize].is_empty()).count();
            // A group (placed children only, at most `max_group`) or a binary split (whose
            // sides may be single placed points).
            prop_assert!(
                (leaves == ch.len() && ch.len() as u32 <= params.max_group) || ch.len() == 2,
                "a merged record with {} children ({leaves} placed)", ch.len()
            );
        }
    }

    /// Every placed point lies on an opaque texel (its `uv` recomputed from its triangle and
    /// barycentric weights), where its colour comes from; `n_pts` points unless the mesh has no
    /// opaque texel. Caught: the retry loop without its alpha test (the seed's "points flying
    /// separately from the tree", C§4.6.3) puts points on transparent texels.
    #[test]
    fn no_point_on_a_transparent_texel(mesh in mesh_strategy(), params in params_strategy()) {
        let set = build(&mesh, &params);
        let mut placed = 0;
        for (i, s) in set.source.iter().enumerate() {
            let Some(s) = s else { continue };
            placed += 1;
            let t = s.triangle as usize;
            let tri = [mesh.indices[3 * t] as usize, mesh.indices[3 * t + 1] as usize, mesh.indices[3 * t + 2] as usize];
            let uv = uv_at(&mesh, tri, s.bary);
            prop_assert_eq!(uv, s.uv);
            let texel = texel_at(&mesh, uv);
            prop_assert!(texel_opaque(texel[3], params.alpha_cutoff), "point {i} on alpha {}", texel[3]);
            prop_assert_eq!(set.records[i].rgba8, u32::from_le_bytes(texel));
        }
        let any_opaque = set.triangle_areas.iter().any(|&a| a > 0.0);
        prop_assert_eq!(placed, if any_opaque { params.n_pts as usize } else { 0 });
    }

    /// Cut mode represents every placed point exactly once at every depth and scale; interval
    /// mode's holes and doubles are only counted. Caught: a placed point's `lower` = its area
    /// (not 0) leaves holes wherever a placed point is bigger than the threshold.
    #[test]
    fn cut_mode_represents_every_point_exactly_once(
        mesh in mesh_strategy(),
        params in params_strategy(),
        log_depth in -1.0f32..4.0,
        scale in 0.2f32..3.0,
        preset in prop::sample::select(DetailPreset::ALL.to_vec()),
        seed_c in any::<bool>(),
    ) {
        let set = build(&mesh, &params);
        let sizes = preset.sizes();
        let th = PointThresholds::new(metric_c(if seed_c { 4.0 } else { 1.0 }), sizes.min_point, sizes.max_point);
        let depth = 10f32.powf(log_depth);
        let drawn = select_tree(&set, PointSelect::Cut, depth, scale, th);
        let counts = representation_counts(&set, &drawn);
        prop_assert!(counts.iter().all(|&c| c == 1), "cut at {depth}: counts {:?}",
            counts.iter().filter(|&&c| c != 1).count());
        let drawn = select_tree(&set, PointSelect::Interval, depth, scale, th);
        let _ = holes_and_doubles(&set, &drawn);
    }

    /// A batch's range (trees at depths `[lo, hi]`, scales `[s_min, s_max]`) holds each of its
    /// trees' drawn records, in both modes. Caught: the interval range's low bound taken with
    /// `s_min` instead of `s_max` drops the small records of the batch's biggest near tree.
    #[test]
    fn batch_range_contains_each_trees_records(
        mesh in mesh_strategy(),
        params in params_strategy(),
        log_lo in -1.0f32..3.5,
        span in 1.0f32..3.0,
        scales in (0.2f32..3.0, 1.0f32..2.0),
        trees in prop::collection::vec((0.0f32..=1.0, 0.0f32..=1.0), 1..8),
        preset in prop::sample::select(DetailPreset::ALL.to_vec()),
    ) {
        let set = build(&mesh, &params);
        let sizes = preset.sizes();
        let th = PointThresholds::new(metric_c(1.0), sizes.min_point, sizes.max_point);
        let lo = 10f32.powf(log_lo);
        let hi = lo * span;
        let (s_min, s_max) = (scales.0, scales.0 * scales.1);
        for mode in PointSelect::ALL {
            let range = batch_range(&set, mode, [lo, hi], [s_min, s_max], th);
            let members = range_records(&set, mode, range);
            // Trees at the corners and at random points of the batch's box.
            let corners = [(0.0, 0.0), (0.0, 1.0), (1.0, 0.0), (1.0, 1.0)];
            for &(u, v) in corners.iter().chain(trees.iter()) {
                let d = (lo + u * (hi - lo)).clamp(lo, hi);
                let s = (s_min + v * (s_max - s_min)).clamp(s_min, s_max);
                for r in select_tree(&set, mode, d, s, th) {
                    prop_assert!(members.binary_search(&r).is_ok(),
                        "{mode:?}: record {r} of tree ({d}, {s}) outside {range:?}");
                }
            }
        }
    }

    /// Beyond the safe change distance every cell-level record left out of the whole-tree node
    /// covers at most `MinTreeLevelPointSize` pixels and every triangle but the tolerated biggest
    /// at most `MaxTreeLevelPointSize`; a tree's selection switches to the whole-tree node there
    /// and not before. Caught: `change_distance` taking the smaller of its two
    /// distances; and [`select_tree_lod`] switching to the whole tree with its comparison
    /// reversed (`depth < s·D_c`).
    #[test]
    fn beyond_the_change_distance_dropped_primitives_are_small(
        mesh in mesh_strategy(),
        params in params_strategy(),
        beyond in 1.0f64..20.0,
        preset in prop::sample::select(DetailPreset::ALL.to_vec()),
    ) {
        let params = PointParams { uplift: params.uplift.max(0.01), ..params };
        let set = build(&mesh, &params);
        let sizes = preset.sizes();
        let c = metric_c(1.0);
        let Some(dc) = mesh_change_distance(&set, c, sizes.min_tree_point, sizes.max_tree_point)
        else {
            prop_assert!(set.records.is_empty());
            return Ok(());
        };
        let d = dc * beyond;
        let px = |a: f32| c * a as f64 / (d * d);
        // The tree's selection switches to the whole-tree node there (unit scale), and not
        // before it.
        let far = select_tree_lod(&set, PointSelect::Cut, d as f32 * 1.000_001, 1.0, c, &sizes);
        prop_assert!(far.whole_tree, "cell level at {d} beyond D_c {dc}");
        let near = select_tree_lod(&set, PointSelect::Cut, (dc * 0.999) as f32, 1.0, c, &sizes);
        prop_assert!(!near.whole_tree, "whole tree at {} before D_c {dc}", dc * 0.999);
        let first_uplifted = set.uplifted.first().copied().unwrap_or(set.records.len() as u32);
        for r in &set.records[..first_uplifted as usize] {
            prop_assert!(px(r.area) <= sizes.min_tree_point as f64 * (1.0 + CHANGE_REL_TOL),
                "dropped point covers {} px at {d} (D_c {dc})", px(r.area));
        }
        let mut tris = set.triangle_areas.clone();
        tris.sort_by(|a, b| b.total_cmp(a));
        let skip = (params.triangle_cutoff as f64 * tris.len() as f64).floor() as usize;
        for &a in &tris[skip.min(tris.len())..] {
            prop_assert!(px(a) <= sizes.max_tree_point as f64 * (1.0 + CHANGE_REL_TOL),
                "kept triangle covers {} px at {d} (D_c {dc})", px(a));
        }
    }

    /// Slip (b): the seed's Y-up tree, unioned on its XY plane, rotated into our Z-up frame
    /// (`(x, y, z) → (x, −z, y)`) and unioned on XZ, keeps every merged area. Caught: the
    /// union taken on our XY plane (`square_xz` on `pos[1]`), the seed's plane read literally.
    #[test]
    fn a_rotated_tree_keeps_its_areas(
        pts in prop::collection::vec(((-3.0f32..3.0, 0.0f32..12.0, -3.0f32..3.0), 0.001f32..1.0), 1..120),
        max_group in 1u32..10,
    ) {
        let y_up: Vec<([f32; 3], f32)> = pts.iter().map(|&((x, y, z), a)| ([x, y, z], a)).collect();
        let z_up: Vec<PlacedPoint> = y_up
            .iter()
            .map(|&(p, a)| PlacedPoint {
                pos: [p[0], -p[2], p[1]],
                normal: [0.0, 0.0, 1.0],
                rgba: [255; 4],
                area: a,
                source: None,
            })
            .collect();
        let set = build_hierarchy(&z_up, [1, 1, 1], max_group, UnionMode::Exact);
        let seed_square = |p: [f32; 3], a: f32| {
            let h = (a as f64).sqrt() * 0.5;
            [p[0] as f64 - h, p[1] as f64 - h, p[0] as f64 + h, p[1] as f64 + h]
        };
        // Placed records keep creation order among equal areas; map them back by position.
        for (i, r) in set.records.iter().enumerate() {
            if set.children[i].is_empty() {
                continue;
            }
            let below: Vec<[f64; 4]> = set
                .leaves_below(i as u32)
                .iter()
                .map(|&l| {
                    let q = set.records[l as usize].pos;
                    // Back to the seed's frame: (x, y, z)_Y-up = (x, z, −y)_Z-up.
                    seed_square([q[0], q[2], -q[1]], set.records[l as usize].area)
                })
                .collect();
            let largest = set.children[i]
                .iter()
                .map(|&c| set.records[c as usize].area as f64)
                .fold(0.0, f64::max);
            let seed = klee_area(&below).max(largest);
            prop_assert!(close(r.area as f64, seed), "record {i}: {} vs the seed's {seed}", r.area);
        }
    }
}

/// Interval mode's holes and doubles on the five species along a distance sweep (reported, not
/// asserted), and cut mode's exactly-once as a count.
#[test]
fn interval_mode_holes_and_doubles_are_reported() {
    let params = PointParams::default();
    let sizes = DetailPreset::Normal.sizes();
    let th = PointThresholds::new(metric_c(1.0), sizes.min_point, sizes.max_point);
    let sets = build_points(species(), &params).unwrap();
    eprintln!(
        "depth m | interval holes | interval doubles | cut non-once (of {} placed x 5)",
        params.n_pts
    );
    for depth in [
        5.0f32, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0, 2000.0, 4000.0,
    ] {
        let (mut holes, mut doubles, mut bad) = (0, 0, 0);
        for set in &sets {
            let (h, d) = holes_and_doubles(
                set,
                &select_tree(set, PointSelect::Interval, depth, 1.0, th),
            );
            holes += h;
            doubles += d;
            let cut = select_tree(set, PointSelect::Cut, depth, 1.0, th);
            bad += representation_counts(set, &cut)
                .iter()
                .filter(|&&c| c != 1)
                .count();
        }
        eprintln!("{depth} | {holes} | {doubles} | {bad}");
        assert_eq!(bad, 0);
    }
}

/// The build is a pure function of mesh and parameters: equal twice, and equal on one thread
/// and on three. Caught: a placement hash seeded with `rayon::current_thread_index()`.
#[test]
fn point_build_is_deterministic_and_thread_independent() {
    let params = PointParams {
        n_pts: 700,
        grid: [2, 2, 2],
        ..PointParams::default()
    };
    let mut meshes = species().to_vec();
    meshes.extend((0..6).map(|s| random_mesh(s, 5, 16, 0.5)));
    let on = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| build_points(&meshes, &params).unwrap())
    };
    let one = on(1);
    assert_eq!(one, on(3));
    assert_eq!(one, on(1));
}

/// Bad point parameters are refused with the field named, before anything is built.
#[test]
fn bad_point_params_are_refused_by_name() {
    let err = build_points(
        species(),
        &PointParams {
            max_group: 0,
            ..PointParams::default()
        },
    )
    .unwrap_err();
    assert_eq!(err.field, "max_group");
    assert!(err.to_string().contains("max_group = 0"), "{err}");
}

/// The measured table of the report (issue 33 item 1): per species and `N_pts`, placed points,
/// records, whole-tree records, build time, and the seed hull's mean overestimate of the exact
/// union over the merged records (`hull / exact`), with the share of merged records whose hull
/// exceeds their children's sum, and the safe change distance at 1280x720, 60°, "Normal". Run with
/// `cargo test -p forestlod-tests --test properties -- --ignored --nocapture measure_point_lod`.
#[test]
#[ignore = "a measurement, printed"]
fn measure_point_lod_table() {
    eprintln!(
        "| mesh | N_pts | placed | records | whole-tree | build ms | hull/exact mean | max | hull > sum | D_c m |"
    );
    eprintln!("|---|---|---|---|---|---|---|---|---|---|");
    let normal = DetailPreset::Normal.sizes();
    for n_pts in [256u32, 1024, 4096] {
        for mesh in species() {
            let params = PointParams {
                n_pts,
                ..PointParams::default()
            };
            let t = std::time::Instant::now();
            let set = build(mesh, &params);
            let ms = t.elapsed().as_secs_f64() * 1e3;
            let (mut sum, mut max, mut merged, mut over) = (0.0f64, 0.0f64, 0usize, 0usize);
            for (i, r) in set.records.iter().enumerate() {
                let ch = &set.children[i];
                if ch.is_empty() {
                    continue;
                }
                let squares: Vec<[f64; 4]> = set
                    .leaves_below(i as u32)
                    .iter()
                    .map(|&l| square_xz(set.records[l as usize].pos, set.records[l as usize].area))
                    .collect();
                let ratio = seed_hull_area(&squares) / r.area as f64;
                let children: f64 = ch
                    .iter()
                    .map(|&c| set.records[c as usize].area as f64)
                    .sum();
                over += (seed_hull_area(&squares) > children * (1.0 + AREA_REL_TOL)) as usize;
                sum += ratio;
                max = max.max(ratio);
                merged += 1;
            }
            eprintln!(
                "| {} | {n_pts} | {} | {} | {} | {ms:.1} | {:.3} | {max:.2} | {:.1} % | {:.0} |",
                mesh.name,
                set.placed().count(),
                set.records.len(),
                set.whole_tree.as_ref().map_or(0, |w| w.records.len()),
                sum / merged.max(1) as f64,
                100.0 * over as f64 / merged.max(1) as f64,
                mesh_change_distance(
                    &set,
                    metric_c(1.0),
                    normal.min_tree_point,
                    normal.max_tree_point
                )
                .unwrap_or(0.0),
            );
        }
    }
}

/// Placement's texel lookup ([`texel_at`]) is the sampler's nearest texel at level 0
/// (`Texture::nearest`), addressing and alpha decode included, for `uv` inside, on the edges of
/// and outside the texture (clamp-to-edge). Caught: `texel_at` rounding to the nearest texel
/// centre (`round` instead of `floor`).
#[test]
fn placement_reads_the_samplers_nearest_texel() {
    use forestlod_reference::sampler::Texture;
    let mesh = random_mesh(3, 1, 16, 0.5);
    let texture = Texture::new(vec![mesh.texture.clone()]).unwrap();
    let mut checked = 0;
    for i in -40..=80 {
        for j in -40..=80 {
            let uv = [i as f32 / 53.0, j as f32 / 47.0];
            let stored = texel_at(&mesh, uv);
            let sampled = texture.nearest(0, 0, uv);
            assert_eq!(stored[3] as f32 / 255.0, sampled[3], "alpha at {uv:?}");
            assert_eq!(
                texel_opaque(stored[3], 0.5),
                sampled[3] >= 0.5,
                "alpha test at {uv:?}"
            );
            checked += 1;
        }
    }
    assert!(checked > 10_000);
}

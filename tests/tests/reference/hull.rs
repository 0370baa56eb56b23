//! The batch hull's geometry (E§7, issue 32 item 4; `forestlod_reference::hull`) against its
//! contract on random batches: conservative (every box corner inside), closed and consistently
//! wound, convex, within the triangle budget, deterministic; degenerate batches do not panic and
//! bad ones are errors naming the box.

use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};

use forestlod_reference::hull::{
    BatchHull, HullBox, HullError, MIN_CUT_REL, ON_PLANE_REL, Triangle, batch_hull, build_hull,
    tree_box,
};
use forestlod_reference::scene::Instance;
use forestlod_shared::{MAX_HULL_TRIANGLES, MeshMeta};
use forestlod_tests::property_config;
use proptest::prelude::*;

/// How far, over the largest coordinate, rounding and the `f32` part of the margin move a hull
/// vertex from where the exact face planes put it: the margin move (`MARGIN_EPS = 4 ε`,
/// ε = `f32::EPSILON`, along up to three face normals, at most about `4 ε √3 ≈ 7 ε`) plus rounding
/// to `f32` (`0.87 ε`).
const VERTEX_MOVE_EPS: f64 = 8.0 * f32::EPSILON as f64;

/// How far, m, a hull vertex may stand off its faces' planes (in or out): the clip keeps a
/// vertex within `ON_PLANE_REL` of the batch's size of a new plane on it, the margin adds that
/// much again, moved along up to three normals (`√3` of it), and [`VERTEX_MOVE_EPS`].
fn vertex_slack(size: f64, big: f64) -> f64 {
    3.0 * ON_PLANE_REL * size + VERTEX_MOVE_EPS * big
}

/// A plane through three vertices each moved by up to `δ` tilts; at distance `R` from the
/// triangle it moves by up to `δ (1 + 2 R / h)`, `h` the triangle's smallest altitude. The plane
/// tests allow exactly that (`conditioning`), so a long thin triangle of a fan (a face with a
/// short edge) is judged by what its vertices can do, and a well-shaped one is judged tightly.
fn conditioning(tri: [[f64; 3]; 3], p: [f64; 3]) -> f64 {
    let e = [0, 1, 2].map(|k| sub(tri[(k + 1) % 3], tri[k]));
    let longest = e.iter().map(|v| dot(*v, *v).sqrt()).fold(0.0, f64::max);
    let n = cross(e[0], e[1]);
    let h = dot(n, n).sqrt() / longest;
    let r = tri
        .iter()
        .map(|q| dot(sub(p, *q), sub(p, *q)).sqrt())
        .fold(0.0, f64::max);
    1.0 + 2.0 * r / h
}

/// Triangles with less area than this fraction of the squared size have no plane worth the name;
/// they are checked by closedness, winding and volume only.
const SLIVER_AREA: f64 = 1e-12;

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn f64s(p: [f32; 3]) -> [f64; 3] {
    p.map(|x| x as f64)
}

/// What [`check`] saw.
#[derive(Debug)]
struct Seen {
    /// Largest distance of a box corner outside a triangle's plane over what is allowed: `≤ 1`.
    outside: f64,
    /// Largest distance of a hull vertex outside a triangle's plane over what is allowed.
    concave: f64,
    /// The hull's volume, m³.
    volume: f64,
}

/// Every corner of every box, `f64`.
fn corners(boxes: &[HullBox]) -> Vec<[f64; 3]> {
    let mut out = Vec::new();
    for (c, h) in boxes {
        for k in 0..8 {
            out.push([0, 1, 2].map(|a| {
                let s = if k >> a & 1 == 0 { -1.0 } else { 1.0 };
                c[a] as f64 + s * h[a] as f64
            }));
        }
    }
    out
}

/// Checks the contract (module docs) and returns what it saw; panics naming the broken property.
fn check(boxes: &[HullBox], tris: &[Triangle]) -> Seen {
    assert!(!tris.is_empty(), "no triangles");
    assert!(
        tris.len() <= MAX_HULL_TRIANGLES as usize,
        "{} triangles, over the budget {MAX_HULL_TRIANGLES}",
        tris.len()
    );
    // Closed and consistently wound: every directed edge once, its reverse once.
    let mut ids: HashMap<[u32; 3], usize> = HashMap::new();
    let mut id = |p: [f32; 3]| {
        let n = ids.len();
        *ids.entry(p.map(f32::to_bits)).or_insert(n)
    };
    let mut edges: HashMap<(usize, usize), u32> = HashMap::new();
    for t in tris {
        let v = t.map(&mut id);
        assert!(
            v[0] != v[1] && v[1] != v[2] && v[0] != v[2],
            "a triangle with a repeated vertex: {t:?}"
        );
        for k in 0..3 {
            *edges.entry((v[k], v[(k + 1) % 3])).or_default() += 1;
        }
    }
    for (&(a, b), &n) in &edges {
        assert_eq!(n, 1, "edge {a}->{b} used {n} times in one direction");
        assert_eq!(
            edges.get(&(b, a)),
            Some(&1),
            "edge {a}->{b} has no opposite twin: the hull is open or wound inconsistently"
        );
    }
    let verts: Vec<[f64; 3]> = {
        let mut v: Vec<([u32; 3], usize)> = ids.iter().map(|(p, i)| (*p, *i)).collect();
        v.sort_by_key(|(_, i)| *i);
        v.iter()
            .map(|(p, _)| p.map(|b| f32::from_bits(b) as f64))
            .collect()
    };
    let all = corners(boxes);
    let big = all
        .iter()
        .chain(&verts)
        .flat_map(|p| p.iter().map(|x| x.abs()))
        .fold(1.0f64, f64::max);
    let (lo, hi) = all.iter().fold(
        ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
        |(lo, hi), p| {
            (
                [0, 1, 2].map(|k| lo[k].min(p[k])),
                [0, 1, 2].map(|k| hi[k].max(p[k])),
            )
        },
    );
    let size = dot(sub(hi, lo), sub(hi, lo)).sqrt();
    let centre = [0, 1, 2].map(|k| (lo[k] + hi[k]) * 0.5);
    // Outward: the signed volume about the batch's centre is positive.
    let mut volume = 0.0;
    for t in tris {
        let [a, b, c] = t.map(|p| sub(f64s(p), centre));
        volume += dot(a, cross(b, c)) / 6.0;
    }
    assert!(volume > 0.0, "signed volume {volume} <= 0: wound inwards");
    // Inside the closed surface as drawn: the winding number of the triangles about every corner
    // is one (solid angles, Van Oosterom and Strackee). This holds for slivers too, whose planes
    // the check below skips: rounding moves the surface by less than the margin.
    for p in &all {
        let mut solid = 0.0;
        for t in tris {
            let [a, b, c] = t.map(|q| sub(f64s(q), *p));
            let (la, lb, lc) = (dot(a, a).sqrt(), dot(b, b).sqrt(), dot(c, c).sqrt());
            let num = dot(a, cross(b, c));
            let den = la * lb * lc + dot(a, b) * lc + dot(a, c) * lb + dot(b, c) * la;
            solid += 2.0 * num.atan2(den);
        }
        let winding = solid / (4.0 * std::f64::consts::PI);
        assert!(
            (winding - 1.0).abs() < 1e-6,
            "corner {p:?} has winding number {winding}: outside the hull (containment)"
        );
    }
    let mut outside = f64::NEG_INFINITY;
    let mut concave = f64::NEG_INFINITY;
    let slack = vertex_slack(size, big);
    for t in tris {
        let tri = t.map(f64s);
        let [a, b, c] = tri;
        let n = cross(sub(b, a), sub(c, a));
        let len = dot(n, n).sqrt();
        if len * 0.5 < SLIVER_AREA * size * size {
            continue;
        }
        let n = n.map(|x| x / len);
        for p in &all {
            let d = dot(n, sub(*p, a));
            let allowed = slack * conditioning(tri, *p);
            outside = outside.max(d / allowed);
            assert!(
                d <= allowed,
                "corner {p:?} stands {d:e} m outside triangle {t:?}, over {allowed:e} (containment)"
            );
        }
        for p in &verts {
            let d = dot(n, sub(*p, a));
            let allowed = slack * conditioning(tri, *p);
            concave = concave.max(d / allowed);
            assert!(
                d <= allowed,
                "vertex {p:?} stands {d:e} m outside triangle {t:?}, over {allowed:e} (convexity)"
            );
        }
    }
    Seen {
        outside,
        concave,
        volume,
    }
}

/// Realistic batches: `n` trees on a square cell of side `cell`, crowns 1-6 m wide half-sizes,
/// 10-30 m tall, on ground of slope `(sx, sy)`, the cell's corner at `offset`.
fn forest(
    trees: &[(f32, f32, f32, f32)],
    cell: f32,
    slope: (f32, f32),
    offset: f32,
) -> Vec<HullBox> {
    trees
        .iter()
        .map(|&(u, v, w, h)| {
            let (x, y) = (u * cell, v * cell);
            let ground = slope.0 * x + slope.1 * y;
            ([offset + x, offset + y, ground + h * 0.5], [w, w, h * 0.5])
        })
        .collect()
}

/// The largest `outside` and `concave` ratios the properties saw so far (as `f64` bits), printed
/// when they grow.
static WORST: [AtomicU64; 2] = [AtomicU64::new(0), AtomicU64::new(0)];

fn record(seen: &Seen) {
    for (slot, value, what) in [
        (&WORST[0], seen.outside, "corner outside a triangle plane"),
        (&WORST[1], seen.concave, "vertex outside a triangle plane"),
    ] {
        let old = f64::from_bits(slot.fetch_max(value.max(0.0).to_bits(), Ordering::Relaxed));
        if value > old {
            println!("worst {what} so far: {value:.3e} of the allowed");
        }
    }
}

fn tree_strategy() -> impl Strategy<Value = (f32, f32, f32, f32)> {
    (0.0f32..1.0, 0.0f32..1.0, 1.0f32..6.0, 10.0f32..30.0)
}

proptest! {
    #![proptest_config(property_config())]

    /// Realistic batches (a few to a few hundred trees, flat or sloped, near the origin or at
    /// 1e5 m): the contract holds, the hull holds the largest tree's box volume, and a second
    /// call gives the same bits.
    #[test]
    fn realistic_batches_keep_the_contract(
        trees in prop::collection::vec(tree_strategy(), 1..200),
        cell in prop::sample::select(vec![20.0f32, 100.0, 500.0]),
        slope in (-0.6f32..0.6, -0.6f32..0.6),
        offset in prop::sample::select(vec![0.0f32, -3000.0, 1e5]),
    ) {
        let boxes = forest(&trees, cell, slope, offset);
        let tris = batch_hull(&boxes).unwrap();
        let seen = check(&boxes, &tris);
        record(&seen);
        let biggest = boxes
            .iter()
            .map(|(_, h)| 8.0 * h.iter().map(|x| *x as f64).product::<f64>())
            .fold(0.0, f64::max);
        prop_assert!(seen.volume >= biggest, "volume {} under a tree's box {biggest}", seen.volume);
        prop_assert_eq!(batch_hull(&boxes).unwrap(), tris);
    }

    /// Arbitrary boxes, points (zero half-size) included, anywhere within a few km: the
    /// contract holds under every budget from a box's 12 up.
    #[test]
    fn arbitrary_boxes_keep_the_contract(
        boxes in prop::collection::vec(
            (
                prop::array::uniform3(-2000.0f32..2000.0),
                prop::array::uniform3(prop_oneof![Just(0.0f32), 0.0f32..80.0]),
            ),
            1..40,
        ),
        budget in 12u32..=MAX_HULL_TRIANGLES,
    ) {
        let h: BatchHull = build_hull(&boxes, budget).unwrap();
        prop_assert!(h.triangles.len() <= budget as usize, "{} > {budget}", h.triangles.len());
        record(&check(&boxes, &h.triangles));
    }
}

#[test]
fn one_box_is_that_box_with_twelve_triangles() {
    let b = ([10.0, -20.0, 7.5], [3.0, 2.0, 7.5]);
    let tris = batch_hull(&[b]).unwrap();
    assert_eq!(tris.len(), 12);
    let seen = check(&[b], &tris);
    let exact = 8.0 * 3.0 * 2.0 * 7.5;
    println!("one box: volume {} vs {exact}", seen.volume);
    // The box moved out by the margin: 4 ε of the largest coordinate (22 m) and a millionth of
    // the size (19 m), 3e-5 m on every side.
    assert!(seen.volume >= exact && seen.volume < exact * (1.0 + 1e-4));
    for t in &tris {
        for p in t {
            for k in 0..3 {
                let off = (p[k] - b.0[k]).abs() - b.1[k];
                assert!(
                    (0.0..1e-4).contains(&off),
                    "vertex {p:?} is not a corner of the box"
                );
            }
        }
    }
}

#[test]
fn degenerate_batches_keep_the_contract() {
    let tree = ([5.0, 5.0, 10.0], [2.0, 2.0, 10.0]);
    let cases: Vec<(&str, Vec<HullBox>)> = vec![
        ("one tree", vec![tree]),
        ("identical trees", vec![tree; 50]),
        (
            "trees on a line",
            (0..40)
                .map(|i| ([i as f32 * 7.0, 3.0, 10.0], [2.0, 2.0, 10.0]))
                .collect(),
        ),
        (
            "trees on a diagonal line",
            (0..40)
                .map(|i| {
                    (
                        [i as f32 * 7.0, i as f32 * 7.0, 10.0 + i as f32],
                        [2.0, 2.0, 10.0],
                    )
                })
                .collect(),
        ),
        ("one point", vec![([1.0, 2.0, 3.0], [0.0; 3])]),
        (
            "points on a line",
            (0..10)
                .map(|i| ([i as f32, 2.0 * i as f32, 3.0 * i as f32], [0.0; 3]))
                .collect(),
        ),
        (
            "points in a tilted plane",
            (0..30)
                .map(|i| {
                    let (u, v) = ((i * 37 % 11) as f32 * 9.0, (i * 13 % 7) as f32 * 13.0);
                    ([u, v, 0.3 * u - 0.2 * v + 5.0], [0.0; 3])
                })
                .collect(),
        ),
        (
            "nested boxes at one spot",
            (1..20)
                .map(|i| {
                    (
                        [4.0, -2.0, 7.0],
                        [i as f32, 20.0 / i as f32, (i % 5) as f32],
                    )
                })
                .collect(),
        ),
        (
            "flat boxes in a plane",
            (0..20)
                .map(|i| {
                    (
                        [(i * 37 % 11) as f32, (i * 13 % 7) as f32, 0.0],
                        [1.0, 1.0, 0.0],
                    )
                })
                .collect(),
        ),
        (
            "a grid of identical trees",
            (0..100)
                .map(|i| {
                    (
                        [(i % 10) as f32 * 50.0, (i / 10) as f32 * 50.0, 10.0],
                        [3.0, 3.0, 10.0],
                    )
                })
                .collect(),
        ),
        (
            "1e5 m offsets",
            (0..60)
                .map(|i| {
                    let f = i as f32;
                    (
                        [
                            1e5 + (f * 37.0) % 500.0,
                            -1e5 + (f * 91.0) % 500.0,
                            300.0 + f * 0.3,
                        ],
                        [2.0 + f % 3.0, 2.0, 8.0 + f % 7.0],
                    )
                })
                .collect(),
        ),
        (
            "a huge box",
            vec![([1e30, -1e30, 0.0], [1e29, 1e29, 1e29]), tree],
        ),
        ("a tiny box", vec![([0.0; 3], [1e-30; 3])]),
    ];
    for (name, boxes) in cases {
        let tris = batch_hull(&boxes).unwrap_or_else(|e| panic!("{name}: {e}"));
        let seen = check(&boxes, &tris);
        println!(
            "{name}: {} triangles, volume {:.4e}, worst corner and vertex over the allowed {:.2e} {:.2e}",
            tris.len(),
            seen.volume,
            seen.outside,
            seen.concave
        );
    }
}

#[test]
fn bad_batches_are_errors_naming_the_box() {
    let ok = ([0.0, 0.0, 5.0], [1.0, 1.0, 5.0]);
    assert_eq!(batch_hull(&[]), Err(HullError::Empty));
    let e = batch_hull(&[ok, ok, ([f32::NAN, 0.0, 0.0], [1.0; 3])]).unwrap_err();
    assert!(
        matches!(
            e,
            HullError::NonFinite {
                index: 2,
                field: "centre",
                ..
            }
        ),
        "{e:?}"
    );
    assert!(e.to_string().contains("box 2"), "{e}");
    let e = batch_hull(&[ok, ([0.0; 3], [1.0, f32::INFINITY, 1.0])]).unwrap_err();
    assert!(
        matches!(
            e,
            HullError::NonFinite {
                index: 1,
                field: "half-size",
                ..
            }
        ),
        "{e:?}"
    );
    let e = batch_hull(&[([0.0; 3], [1.0, -1.0, 1.0])]).unwrap_err();
    assert!(
        matches!(e, HullError::NegativeExtent { index: 0, .. }),
        "{e:?}"
    );
    let e = batch_hull(&[ok, ([3e38, 0.0, 0.0], [1.0; 3])]).unwrap_err();
    assert!(matches!(e, HullError::OutOfRange { index: 1, .. }), "{e:?}");
    assert_eq!(build_hull(&[ok], 11), Err(HullError::Budget(11)));
}

#[test]
fn the_hull_is_the_same_from_any_thread() {
    let scattered: Vec<HullBox> = (0..300)
        .map(|i| {
            let f = i as f32;
            (
                [
                    (f * 37.3) % 500.0,
                    (f * 91.7) % 500.0,
                    0.2 * ((f * 91.7) % 500.0) + 10.0,
                ],
                [2.0 + f % 3.0, 2.0 + f % 4.0, 5.0 + f % 10.0],
            )
        })
        .collect();
    // Symmetric batches: many candidates cut equally deep, so only a fixed tie order gives the
    // same hull twice.
    let diamond: Vec<HullBox> = [[0.0, 100.0], [100.0, 0.0], [0.0, -100.0], [-100.0, 0.0]]
        .iter()
        .map(|&[x, y]| ([x, y, 10.0], [3.0, 3.0, 10.0]))
        .collect();
    let ring: Vec<HullBox> = (0..12)
        .map(|i| {
            let a = i as f32 * std::f32::consts::PI / 6.0;
            ([200.0 * a.cos(), 200.0 * a.sin(), 12.0], [4.0, 4.0, 12.0])
        })
        .collect();
    for boxes in [scattered, diamond, ring] {
        let here = batch_hull(&boxes).unwrap();
        let there: Vec<Vec<Triangle>> = std::thread::scope(|s| {
            let handles: Vec<_> = (0..4)
                .map(|_| s.spawn(|| batch_hull(&boxes).unwrap()))
                .collect();
            handles.into_iter().map(|h| h.join().unwrap()).collect()
        });
        for t in there {
            assert_eq!(t, here);
        }
    }
}

/// The hull is tight, not merely valid: a few trees end at their exact hull (no candidate left
/// to cut deeper than the smallest cut), and on a slope the budgeted hull is well under the
/// box of the batch (10-30 m trees on 150 m of rise fill a slab of about a sixth of the box; the
/// hull measured 0.16 of it; the module's table has the greedy within 1.1 of the exact hull).
#[test]
fn the_hull_is_tight() {
    let few: Vec<HullBox> = [
        [10.0, 20.0, 12.0],
        [300.0, 50.0, 25.0],
        [120.0, 410.0, 18.0],
    ]
    .iter()
    .map(|&[x, y, h]| ([x, y, h * 0.5], [3.0, 3.0, h * 0.5]))
    .collect();
    let h = build_hull(&few, u32::MAX).unwrap();
    let size = 500.0f64;
    println!(
        "three trees: excess {} m, {} triangles",
        h.excess,
        h.triangles.len()
    );
    assert!(h.excess <= MIN_CUT_REL * size, "excess {} m", h.excess);
    let sloped: Vec<HullBox> = (0..100)
        .map(|i| {
            let f = i as f32;
            let (x, y) = ((f * 37.3) % 500.0, (f * 91.7) % 500.0);
            let h = 10.0 + (f * 7.0) % 20.0;
            ([x, y, 0.3 * x + h * 0.5], [3.0, 3.0, h * 0.5])
        })
        .collect();
    let tris = batch_hull(&sloped).unwrap();
    let seen = check(&sloped, &tris);
    let (lo, hi) = sloped.iter().fold(
        ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
        |(lo, hi), (c, e)| {
            (
                [0, 1, 2].map(|k| lo[k].min(c[k] as f64 - e[k] as f64)),
                [0, 1, 2].map(|k| hi[k].max(c[k] as f64 + e[k] as f64)),
            )
        },
    );
    let boxed: f64 = (0..3).map(|k| hi[k] - lo[k]).product();
    println!(
        "slope: hull {:.4e} m³, box {boxed:.4e} m³, ratio {:.3}",
        seen.volume,
        seen.volume / boxed
    );
    assert!(seen.volume < 0.25 * boxed);
}

#[test]
fn a_tree_box_holds_its_rotated_mesh_box() {
    let mesh = MeshMeta {
        bbox_min: [-2.0, -1.0, 0.0],
        bbox_max: [3.0, 1.5, 12.0],
        ..bytemuck::Zeroable::zeroed()
    };
    for yaw in [0.0f32, 0.3, 1.0, 2.5, -4.0] {
        let t = Instance {
            position: [1e5 + 0.3, -7.1, 200.0],
            yaw,
            scale: 1.7,
            mesh: 0,
        };
        let (c, h) = tree_box(&t, &mesh);
        let (s, co) = (yaw as f64).sin_cos();
        for k in 0..8 {
            let l = [0, 1, 2].map(|a| {
                let v = if k >> a & 1 == 0 {
                    mesh.bbox_min[a]
                } else {
                    mesh.bbox_max[a]
                };
                v as f64 * 1.7
            });
            let w = [
                t.position[0] as f64 + co * l[0] - s * l[1],
                t.position[1] as f64 + s * l[0] + co * l[1],
                t.position[2] as f64 + l[2],
            ];
            for a in 0..3 {
                assert!(
                    (w[a] - c[a] as f64).abs() <= h[a] as f64,
                    "yaw {yaw}: corner {w:?} outside box {c:?} ± {h:?}"
                );
            }
        }
    }
}

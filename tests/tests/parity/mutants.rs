//! The CI-sized mutation subset (issue 36): WGSL mutants that the suite killed when the
//! mutation sample was triaged (`experiments/results/mutation/README.md`), each of which must
//! **stay killed by the test named beside it**. A mutant costs no rebuild: its shader text is
//! written to a file and handed to a child run of **this** test binary through the mutation hook
//! (`FORESTLOD_MUTANT_WGSL=<file>=<path>`, `forestlod_gpu::shaders::mutant_or`), filtered to the
//! killing test alone. The mutant is killed when that test fails (the child exits non-zero and
//! lists it under `failures:`); a child still running at [`MUTANT_DEADLINE`] counts as a
//! **survivor**, not a kill (issue 36: a kill must be a named failing test, not a timeout).
//!
//! Each entry names its line by text, not by number, so that an edit elsewhere in the shader
//! does not move it; a line that no longer occurs exactly once fails the test with a message
//! saying which entry to update. The children run one at a time (each already uses every core
//! through lavapipe); proptest shrinking is cut short in them (`PROPTEST_MAX_SHRINK_ITERS=0`),
//! since only the failure, not the smallest case, is wanted.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use forestlod_harness::context::gpu_context;

/// Longest a child may run. The slowest killing test (`every_stage::walk_mips`, the 4096² mips
/// of three modes on the reference) takes about 45 s on the correct build on this loaded 2-core
/// machine in debug; a mutant that makes a killer run past 4 times that is not killed by a
/// failing test and must be triaged like a survivor.
const MUTANT_DEADLINE: Duration = Duration::from_secs(180);

/// One mutant (module docs): in `file` (under `gpu/src/shaders/`), on the one line that contains
/// `line`, the first `before` becomes `after`; `killer` is the test (path in this binary) that
/// must fail; `why` says what the change breaks.
struct Mutant {
    file: &'static str,
    line: &'static str,
    before: &'static str,
    after: &'static str,
    killer: &'static str,
    why: &'static str,
}

/// The subset (module docs).
const MUTANTS: &[Mutant] = &[
    Mutant {
        file: "common.wgsl",
        line: "let partial = n.depth < max_cull_depth && !aabb_planes(v.frustum.planes, bc, e, v.eye, true);",
        before: "bc, e, v.eye, true",
        after: "vec3<f32>(n.center[0], n.center[1], n.center[2]), e, v.eye, true",
        killer: "hier_select::gpu_cut_on_frustum_straddling_boxes",
        why: "the octree's partial-visibility test on the sphere centre (issue 36, class 5)",
    },
    Mutant {
        file: "common.wgsl",
        line: "recurse = v.lod_levels < 2u || aabb_distance(bc, e, v.eye) < v.fade_end || partial;",
        before: "< v.fade_end",
        after: "< v.fade_start",
        killer: "hier_select::gpu_cut_on_frustum_straddling_boxes",
        why: "G§3's dist_to compared with the fade start (octree-euclidean, issue 36, class 3)",
    },
    Mutant {
        file: "common.wgsl",
        line: "visible = visible && (p.x * rel.x + p.y * rel.y + p.z * rel.z + p.w >= -radius - m);",
        before: ">= -radius - m",
        after: ">= -radius - m || i == 5u",
        killer: "select::gpu_select_with_the_far_plane_before_the_draw_distance",
        why: "the far plane dropped from the sphere test",
    },
    Mutant {
        file: "common.wgsl",
        line: "return ViewInterval(d, d - r - m, d + r + m);",
        before: "d + r + m)",
        after: "d + r - m)",
        killer: "hier_select::gpu_cut_on_box_knife_edges",
        why: "the box interval's far end loses its margin: a node at the fade start drops its LOD1 \
              (issue 36's WGSL survivor 203, inside the ambiguity the random property excuses)",
    },
    Mutant {
        file: "draw.wgsl",
        line: "if texel.a < u.alpha_cutoff {",
        before: " < ",
        after: " <= ",
        killer: "every_stage::walk_draw",
        why: "the alpha test keeps a texel at the cutoff no more (cutoff 0 and 1, issue 36, class 4)",
    },
    Mutant {
        file: "draw.wgsl",
        line: "if !tree_within_draw_distance(sphere.center) {",
        before: "if !",
        after: "if false && !",
        killer: "draw::unrefined_mesh_batches_straddling_the_draw_distance",
        why: "the draw stage's per-tree draw-distance discard dropped (issue 36, class 4)",
    },
    Mutant {
        file: "draw.wgsl",
        line: "let ly = (mesh.bbox_min[1] + mesh.bbox_max[1]) * 0.5 * t.scale;",
        before: "0.5",
        after: "1.5",
        killer: "draw::off_axis_mesh_near_the_draw_distance",
        why: "the tree sphere's local centre off in y (issue 15's survivor 158)",
    },
    Mutant {
        file: "select.wgsl",
        line: "    if lod0 && lod1 {",
        before: "lod0 && lod1",
        after: "lod1",
        killer: "counters::gpu_counters_equal_their_recount",
        why: "the transition-batch counter counts every LOD1 batch (issue 36, class 6)",
    },
    Mutant {
        file: "refine.wgsl",
        line: "atomicAdd(&refine_counters.trees_kept, kept);",
        before: "kept)",
        after: "len)",
        killer: "counters::gpu_counters_equal_their_recount",
        why: "refine counts the trees tested as kept (issue 36, class 6)",
    },
    Mutant {
        file: "refine.wgsl",
        line: "let y = min(slots, u.max_workgroups);",
        before: "min(",
        after: "max(",
        killer: "refine::refine_dispatch_grid_follows_its_formula",
        why: "refine's indirect grid takes the per-dimension limit, not the slot count, as its rows \
              (issue 36's WGSL sample, survivor 626: the same result, slowly, below the limit)",
    },
    Mutant {
        file: "coalesce.wgsl",
        line: "&& pc.first_instance + pc.instance_count == c.first_instance;",
        before: "pc.instance_count ==",
        after: "pc.instance_count + 1u ==",
        killer: "hier_select::gpu_coalescing_spans_scan_chunks",
        why: "coalescing merges commands that are not contiguous",
    },
    Mutant {
        file: "coalesce.wgsl",
        line: "if j + 1u == n || is_head(j + 1u) {",
        before: "j + 1u == n",
        after: "j + 1u != n",
        killer: "hier_select::gpu_coalescing_ignores_stale_slots_past_the_count",
        why: "the last run ends where a stale slot past the count says (issue 36's WGSL sample, \
              survivor 46: lavapipe's serial order hides the race it also makes)",
    },
    Mutant {
        file: "command_order.wgsl",
        line: "return ka < kb || (ka == kb && ia < ib);",
        before: "ia < ib",
        after: "ia > ib",
        killer: "hier_select::gpu_cut_on_frustum_straddling_boxes",
        why: "ties of the front-to-back key broken against the unsorted order (passes \
              gpu_front_to_back_spans_workgroups, whose keys are distinct)",
    },
    Mutant {
        file: "mips.wgsl",
        line: "return tables[TABLE_UNORM_DECODE + encode_byte(alpha, TABLE_UNORM_ENCODE)] > u.alpha_ref;",
        before: "] > u.alpha_ref",
        after: "] >= u.alpha_ref",
        killer: "every_stage::walk_mips",
        why: "the mips' alpha test passes a texel at the cutoff (alpha_cutoff 0 and 1, issue 36, class 4)",
    },
    Mutant {
        file: "bake.wgsl",
        line: "let up = p.z * c - p.x * s;",
        before: " - ",
        after: " + ",
        killer: "bake::gpu_bake_equals_the_reference_at_the_extremes",
        why: "the billboard frame's up axis tilted the wrong way",
    },
    Mutant {
        file: "primitive.wgsl",
        line: "let b2 = ox * dir.x + oy * dir.y;",
        before: " + ",
        after: " - ",
        killer: "baselines::gpu_baseline_images_match_the_reference",
        why: "the Primitive baseline's trunk-cylinder intersection",
    },
    Mutant {
        file: "primitive.wgsl",
        line: "best = take(best, (-b + s) / a, t_min);",
        before: "-b + s",
        after: "-b - s",
        killer: "baselines::gpu_baseline_images_match_the_reference",
        why: "the Primitive crown sphere's far root lost, which alone decides with the crown \
              across the near plane (issue 36's WGSL sample, survivor 581)",
    },
    Mutant {
        file: "common.wgsl",
        line: "let turns = (atan2(h_y, h_x) - yaw) * bitcast<f32>(AZIMUTH_TURN_BITS);",
        before: "- yaw",
        after: "+ yaw",
        killer: "draw::gpu_draw_matches_the_reference_with_azimuth_views",
        why: "the tree's yaw added to the eye's azimuth instead of subtracted (issue 30)",
    },
    Mutant {
        file: "cull.wgsl",
        line: "if count > 0u {",
        before: "count > 0u",
        after: "count > 1u",
        killer: "baselines::gpu_cull_matches_per_tree_culling",
        why: "a mesh with one visible tree gets no draw command",
    },
    Mutant {
        file: "depth_copy.wgsl",
        line: "out[id.y * size.x + id.x] = textureLoad(depth_texture, vec2<i32>(id.xy), 0).x;",
        before: "size.x + id.x",
        after: "size.x - id.x",
        killer: "draw::one_draw_call_and_stale_slots_past_the_count_are_ignored",
        why: "the depth readback by compute scrambles its rows (issue 36's WGSL sample, survivor \
              268: no test ran that path on lavapipe, and the module bypassed the mutation hook)",
    },
];

fn shader_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../gpu/src/shaders")
}

/// The mutated text of `m`'s file, or why the entry no longer applies.
fn mutate(m: &Mutant) -> Result<String, String> {
    let path = shader_dir().join(m.file);
    let src = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    let hits: Vec<usize> = src
        .lines()
        .enumerate()
        .filter(|(_, l)| l.contains(m.line))
        .map(|(i, _)| i)
        .collect();
    let [at] = hits[..] else {
        return Err(format!(
            "{}: the line `{}` occurs {} times (must be once): update the entry",
            m.file,
            m.line,
            hits.len()
        ));
    };
    let mut out: Vec<String> = src.lines().map(str::to_string).collect();
    if !out[at].contains(m.before) {
        return Err(format!(
            "{}:{}: `{}` not on the line `{}`",
            m.file,
            at + 1,
            m.before,
            out[at]
        ));
    }
    out[at] = out[at].replacen(m.before, m.after, 1);
    Ok(out.join("\n") + "\n")
}

/// Runs `killer` alone in a child of this binary with the mutant hook set; `Ok(seconds)` when it
/// failed (killed), `Err(what happened)` otherwise.
fn run_killer(m: &Mutant, mutant_path: &Path, log: &Path) -> Result<f64, String> {
    let exe = std::env::current_exe().map_err(|e| format!("this test binary: {e}"))?;
    let out = std::fs::File::create(log).map_err(|e| format!("{}: {e}", log.display()))?;
    let err = out.try_clone().map_err(|e| e.to_string())?;
    let started = Instant::now();
    let mut child = Command::new(exe)
        .args([m.killer, "--exact", "--test-threads=1"])
        .env(
            "FORESTLOD_MUTANT_WGSL",
            format!("{}={}", m.file, mutant_path.display()),
        )
        .env("PROPTEST_MAX_SHRINK_ITERS", "0")
        .stdin(Stdio::null())
        .stdout(out)
        .stderr(err)
        .spawn()
        .map_err(|e| format!("spawn: {e}"))?;
    let status = loop {
        if let Some(status) = child.try_wait().map_err(|e| e.to_string())? {
            break status;
        }
        if started.elapsed() > MUTANT_DEADLINE {
            let _ = child.kill();
            let _ = child.wait();
            return Err(format!(
                "still running after {MUTANT_DEADLINE:?}: a timeout, not a kill"
            ));
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let seconds = started.elapsed().as_secs_f64();
    let text = std::fs::read_to_string(log).unwrap_or_default();
    // `--exact` with a name no test has runs nothing and passes: that is no kill either.
    if !text.contains("running 1 test") {
        return Err(format!(
            "no test named {} in this binary (log {}): update the entry",
            m.killer,
            log.display()
        ));
    }
    if status.success() {
        return Err(format!(
            "{} passed ({seconds:.1} s): the mutant survives",
            m.killer
        ));
    }
    // libtest lists the failed tests after `failures:`, one per line, indented by four spaces
    // (the `test NAME ... FAILED` line may be split by the adapter's messages on stderr).
    let listed = text
        .split("\nfailures:\n")
        .skip(1)
        .any(|part| part.lines().any(|l| l == format!("    {}", m.killer)));
    if !listed {
        return Err(format!(
            "the child failed ({status}) without `{}` failing (log {})",
            m.killer,
            log.display()
        ));
    }
    Ok(seconds)
}

#[test]
fn ci_mutants_stay_killed() {
    if gpu_context().is_none() {
        eprintln!("mutants: no GPU adapter (FORESTLOD_ALLOW_NO_GPU=1)");
        return;
    }
    // A child of a child would recurse: the hook set means this run is a mutant's.
    if std::env::var_os("FORESTLOD_MUTANT_WGSL").is_some() {
        panic!("ci_mutants_stay_killed must not run under a mutant (FORESTLOD_MUTANT_WGSL is set)");
    }
    assert!(
        (10..=20).contains(&MUTANTS.len()),
        "the CI subset holds 10-20 mutants, not {}",
        MUTANTS.len()
    );
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("ci-mutants");
    std::fs::create_dir_all(&dir).expect("create the mutants folder");
    let started = Instant::now();
    let mut problems = Vec::new();
    for (i, m) in MUTANTS.iter().enumerate() {
        let what = format!(
            "mutant {i} {}: `{}` -> `{}` on `{}` ({})",
            m.file, m.before, m.after, m.line, m.why
        );
        let text = match mutate(m) {
            Ok(t) => t,
            Err(e) => {
                problems.push(format!("{what}: {e}"));
                continue;
            }
        };
        let path = dir.join(format!("{i}-{}", m.file));
        std::fs::write(&path, text).expect("write the mutant");
        match run_killer(m, &path, &dir.join(format!("{i}.log"))) {
            Ok(s) => eprintln!("{what}: killed by {} in {s:.1} s", m.killer),
            Err(e) => problems.push(format!("{what}: {e}")),
        }
    }
    eprintln!(
        "mutants: {} of {} killed in {:.1} s",
        MUTANTS.len() - problems.len(),
        MUTANTS.len(),
        started.elapsed().as_secs_f64()
    );
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

//! The WGSL structs of `common.wgsl`, `select.wgsl` and `primitive.wgsl` (the Primitive baseline's
//! `ProxyRecord`) have the layout of their Rust twins: every
//! member at the same byte offset, every struct the same size. Checked with naga's reflection (the
//! offsets naga computes are the ones wgpu's backends use), so a drifting field fails here rather
//! than as garbage in a parity test. Also validates the modules, including that `Camera`
//! and `SelectUniform` (with the `ViewUniform` every selection-like stage embeds) are legal in the
//! uniform address space.

use forestlod_gpu::shaders::with_common;
use forestlod_gpu::{CoalesceUniform, CullTree, HierUniform, SelectUniform};
use forestlod_gpu::{coalesce, cull, hier_select, primitive, select};
use forestlod_shared::points::PointRecord;
use forestlod_shared::{
    BatchMeta, Camera, CommandData, DrawCommand, FarCell, FarNode, FarVertex, FrustumPlanes,
    MeshMeta, NodeMeta, ProxyRecord, SelectCounters,
};

/// The crate's own layout-test support (`gpu/src/wgsl_layout.rs`), shared with its unit tests.
#[path = "../src/wgsl_layout.rs"]
mod wgsl_layout;
use wgsl_layout::{
    RustLayout, assert_layout, rust_layout, validate, view_uniform_layout, wgsl_layout,
};

fn rust_layouts() -> Vec<RustLayout> {
    vec![
        rust_layout!(Camera {
            eye,
            fov_y,
            forward,
            near,
            up,
            far,
            width,
            height,
            tile
        }),
        rust_layout!(BatchMeta {
            center,
            radius,
            extent,
            mesh,
            box_center,
            len,
            cell,
            offset,
            _pad0
        }),
        rust_layout!(DrawCommand {
            index_count,
            instance_count,
            first_index,
            base_vertex,
            first_instance
        }),
        rust_layout!(CommandData {
            fade_start,
            fade_end,
            batch,
            mesh,
            lod,
            billboard,
            fading,
            first_tree,
            group_len,
            _pad0
        }),
        rust_layout!(MeshMeta {
            first_index,
            index_count,
            first_vertex,
            vertex_count,
            bbox_min,
            billboard_half_width,
            bbox_max,
            sphere_radius,
            area_size,
            error_size,
            _pad0,
            _pad1
        }),
        rust_layout!(SelectCounters {
            batches_tested,
            culled_distance,
            culled_frustum,
            commands,
            lod0_commands,
            lod1_commands,
            transition_batches,
            instances
        }),
        rust_layout!(CullTree {
            center,
            radius,
            mesh,
            scale
        }),
        rust_layout!(FrustumPlanes { planes }),
        rust_layout!(PointRecord {
            pos,
            area,
            lower,
            parent_area,
            normal,
            rgba8,
            parent,
            leaves,
            _pad
        }),
        view_uniform_layout(),
        rust_layout!(SelectUniform {
            view,
            batch_count,
            mesh_count,
            billboard_first_index,
            billboard_index_count
        }),
    ]
}

#[test]
fn wgsl_structs_match_their_rust_twins() {
    // Bind the uniform-side structs as uniforms so validation checks their uniform layout rules.
    let source = format!(
        "{}\n@group(9) @binding(1) var<uniform> layout_camera: Camera;\n",
        select::SOURCE.module()
    );
    let module = validate(&source);
    let primitive = validate(&primitive::SOURCE.module());
    let mut checked = 0;
    let primitive_layouts = vec![rust_layout!(ProxyRecord {
        crown_radius,
        crown_z,
        trunk_radius,
        bottom_z,
        color,
        _pad0
    })];
    let layouts = rust_layouts()
        .into_iter()
        .map(|l| (l, &module))
        .chain(primitive_layouts.into_iter().map(|l| (l, &primitive)));
    for (rust, module) in layouts {
        assert_layout(module, &rust);
        checked += 1;
        eprintln!(
            "{}: {} members, {} bytes: layouts equal",
            rust.name,
            rust.fields.len(),
            rust.size
        );
    }
    assert_eq!(checked, 12);
}

/// `common.wgsl` with its generated constants and no stage validates.
#[test]
fn common_wgsl_is_valid_alone() {
    validate(&with_common(""));
}

/// The modules that repeat shared structs in their own files (`cull.wgsl`'s `SelectCounters`
/// use, `primitive.wgsl`'s `ProxyRecord`) validate, and `common.wgsl`'s shared structs keep their
/// layout there too.
#[test]
fn cull_and_primitive_modules_validate() {
    for source in [cull::SOURCE.module(), primitive::SOURCE.module()] {
        let module = validate(&source);
        for name in ["SelectCounters", "DrawCommand", "CommandData", "MeshMeta"] {
            assert_eq!(
                wgsl_layout(&module, name),
                wgsl_layout(&validate(&with_common("")), name),
                "{name}"
            );
        }
    }
}

/// `hier_select.wgsl`'s structs (issue 13): `NodeMeta` (from `common.wgsl`) and the stage's
/// uniform have their Rust twins' layouts (its atomic counters are `common.wgsl`'s
/// `SelectCountersAtomic`, checked below).
#[test]
fn hier_select_structs_match_their_rust_twins() {
    let module = validate(&format!(
        "{}\n@group(9) @binding(0) var<uniform> layout_hier: HierUniform;\n",
        hier_select::SOURCE.module()
    ));
    assert_layout(
        &module,
        &rust_layout!(NodeMeta {
            center,
            radius,
            extent,
            mesh,
            box_center,
            len,
            offset,
            parent,
            depth,
            child_count
        }),
    );
    assert_layout(
        &module,
        &rust_layout!(HierUniform {
            view,
            node_count,
            mode,
            max_cull_depth,
            billboard_first_index,
            billboard_index_count,
            far_kind,
            far_start,
            far_ratio,
            far_first_index,
            _pad0,
            _pad1,
            _pad2
        }),
    );
    // The far level's records (issue 32, `common.wgsl`): the cut binds `FarNode`s; the draw
    // reads all three from one word buffer at these strides (`gpu/src/draw.rs` `far_words`).
    assert_layout(
        &module,
        &rust_layout!(FarNode {
            cell_offset,
            cell_count,
            hull_offset,
            hull_count
        }),
    );
    assert_layout(
        &module,
        &rust_layout!(FarCell {
            center,
            extent,
            colours
        }),
    );
    assert_layout(&module, &rust_layout!(FarVertex { position, colour }));
}

/// `coalesce.wgsl`'s uniform has its Rust twin's layout (its atomic counters are `common.wgsl`'s
/// `SelectCountersAtomic`, checked below).
#[test]
fn coalesce_structs_match_their_rust_twins() {
    let module = validate(&format!(
        "{}\n@group(9) @binding(0) var<uniform> layout_coalesce: CoalesceUniform;\n",
        coalesce::SOURCE.module()
    ));
    assert_layout(
        &module,
        &rust_layout!(CoalesceUniform {
            capacity,
            mode,
            _pad0,
            _pad1
        }),
    );
}

/// The atomic counters struct (`common.wgsl`, written by `select.wgsl`, `hier_select.wgsl` and
/// `coalesce.wgsl`) must have the plain counters' layout, since both name one buffer: the draw
/// stage's count buffer.
#[test]
fn atomic_counters_have_the_counters_layout() {
    let module = validate(&select::SOURCE.module());
    let (plain, plain_span) = wgsl_layout(&module, "SelectCounters").unwrap();
    let (atomic, atomic_span) = wgsl_layout(&module, "SelectCountersAtomic").unwrap();
    assert_eq!(plain, atomic);
    assert_eq!(plain_span, atomic_span);
}

/// The occlusion stage's atomic counters (`common.wgsl`, written by `occlude.wgsl`) have the
/// layout of `forestlod_shared::OcclusionCounters` (issue 31), which the driver reads back from
/// the same bytes.
#[test]
fn occlusion_counters_have_the_shared_layout() {
    use forestlod_shared::OcclusionCounters;
    let module = validate(&forestlod_gpu::occlude::SOURCE.module());
    let want = rust_layout!(OcclusionCounters {
        early,
        tested,
        occluded,
        offscreen,
        late,
        unbounded,
        _pad0
    });
    let (fields, span) = wgsl_layout(&module, "OcclusionCountersAtomic").unwrap();
    let names: Vec<_> = want
        .fields
        .iter()
        .map(|(n, o)| (n.to_string(), *o as u32))
        .collect();
    assert_eq!(fields, names, "member offsets");
    assert_eq!(span as usize, want.size, "size");
}

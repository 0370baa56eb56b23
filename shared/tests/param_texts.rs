//! Pins the refusal reason and the `--help` line of every parameter of the table, byte for byte,
//! as they were written by hand before the choice parameters' texts were generated from their
//! enums' choice lists (`registry.rs`). A hand list of choice names here is the point: this file
//! is the one place allowed to spell them out (`tests/tests/no_hand_lists.rs` exempts it).

use forestlod_shared::PARAMS;

/// `(name, reason, help)` of every parameter, in table order.
const PINNED: [(&str, &str, &str); 56] = [
    (
        "grid_size",
        "expected a finite size in 0.01..=1e7 m",
        "Batch grid cell size, metres (E§4.2)",
    ),
    (
        "angle_count",
        "expected 1..=91 elevation angles",
        "Number of billboard elevation angles K (E§3.3)",
    ),
    (
        "texture_size",
        "expected a power of two in 1..=4096",
        "Billboard texture side r, a power of two (E§3.3)",
    ),
    (
        "lod_levels",
        "expected 1 (meshes only), 2 (meshes then billboards) or 3 (then the far level of far-lod)",
        "LOD levels: 1 (meshes only), 2 (then billboards) or 3 (then far-lod, issue 32)",
    ),
    (
        "lod1_transition",
        "expected a finite distance in 0..=1e7 m",
        "View depth where billboards have fully replaced meshes, metres (E§3.5)",
    ),
    (
        "fade_width",
        "expected a finite width in 0..=1e7 m",
        "Width of the fade band ending at the transition, metres (E§3.5)",
    ),
    (
        "draw_distance",
        "expected a finite distance in 0..=1e7 m",
        "Draw distance, metres (E§4.4)",
    ),
    (
        "alpha_cutoff",
        "expected a finite alpha in 0..=1",
        "Alpha-test cutoff of foliage, in 0..=1",
    ),
    (
        "fade_mode",
        "expected 0 (none), 1 (alpha), 2 (dither) or 3 (dither-sequential)",
        "Fade mode: none, alpha (E§4.4), dither, dither-sequential (G§4)",
    ),
    (
        "mip_mode",
        "expected 0 (alpha-aware), 1 (box) or 2 (coverage)",
        "Billboard mip mode: alpha-aware, box, coverage (E§3.3.2)",
    ),
    (
        "angle_index_mode",
        "expected 0 (nearest) or 1 (eq31-clamped)",
        "Billboard layer index: nearest, eq31-clamped (E Eq. 3.1)",
    ),
    (
        "tree_cull",
        "expected 0 (none), 1 (lod0) or 2 (all)",
        "Per-tree culling after selection (refine, beyond the thesis): none, lod0, all",
    ),
    (
        "hierarchy",
        "expected 0 (grid), 1 (grid-aabb), 2 (quadtree), 3 (octree), 4 (octree-euclidean) or 5 (kmeans)",
        "Tree grouping: grid (E§4.2), grid-aabb (E§7 bounds), quadtree (C§4.5), octree (G§3), octree-euclidean (G§3 as written, not conservative), kmeans (E§7 density-aware batches)",
    ),
    (
        "nodes_per_node",
        "expected 2..=1048576 children or trees per node",
        "Most children of a quadtree node and most trees of a hierarchy leaf (C§4.5 NodesPerNode)",
    ),
    (
        "max_cull_depth",
        "expected a depth in 0..=64",
        "Octree depth below which partially visible nodes recurse (G§3 max_cull_depth)",
    ),
    (
        "coalesce",
        "expected 0 (off) or 1 (on)",
        "Merge adjacent draw commands of the hierarchical cut (issue 13): off, on",
    ),
    (
        "command_order",
        "expected 0 (node) or 1 (front-to-back)",
        "Order of the hierarchical cut's commands after coalescing: node, front-to-back (E§7 distance-sorted)",
    ),
    (
        "lod_metric",
        "expected 0 (distance), 1 (pixel-area), 2 (pixel-area-seed) or 3 (screen-error)",
        "Where a tree changes to its billboard (issue 29): distance (E§4.3), pixel-area (C§4.6.3, corrected), pixel-area-seed (C Eq. 4.2 as written), screen-error (3D Tiles SSE)",
    ),
    (
        "lod_pixel_area",
        "expected a finite area in 1e-6..=1e9 px²",
        "Pixel-area metrics: billboard once the tree's opaque area covers at most this many px² (C§4.6.3)",
    ),
    (
        "lod_screen_error",
        "expected a finite error in 1e-6..=1e9 px",
        "Screen-error metric: billboard once its geometric error covers at most this many px (3D Tiles)",
    ),
    (
        "subset_mode",
        "expected 0 (off), 1 (thin) or 2 (thin-scale)",
        "Far-field subsets of each batch's trees (issue 29): off, thin (E§7), thin-scale",
    ),
    (
        "subset_distance",
        "expected a finite distance in 0..=1e7 m",
        "View depth past which batches draw a thinning subset of their trees, metres (E§7)",
    ),
    (
        "subset_min",
        "expected a finite density in 0.001..=1",
        "Least density of a far-field subset, in 0.001..=1 (E§7)",
    ),
    (
        "shading",
        "expected 0 (unlit), 1 (sun-depth) or 2 (sun-depth-plane)",
        "Tree shading (issue 30): unlit, sun-depth (G§5 Fig. 8), sun-depth-plane (G§5 Fig. 9)",
    ),
    (
        "sun_azimuth",
        "expected a finite azimuth in -360..=360 degrees",
        "Sun azimuth, degrees counter-clockwise from +X (G§5)",
    ),
    (
        "sun_elevation",
        "expected a finite elevation in 0..=90 degrees",
        "Sun elevation above the horizon, degrees (G§5)",
    ),
    (
        "ambient",
        "expected a finite level in 0..=1",
        "Ambient level of sun-depth shading: the lightness of a crown's far side, in 0..=1 (G§5)",
    ),
    (
        "dither_space",
        "expected 0 (screen) or 1 (texture)",
        "Where the dithered fades' threshold comes from (issue 30): screen, texture (G§4)",
    ),
    (
        "fade_granularity",
        "expected 0 (fragment) or 1 (tree)",
        "What a fade's progress through the band is taken from (issue 30): fragment, tree (G§4)",
    ),
    (
        "noise_size",
        "expected a power of two in 1..=4096",
        "Side of the texture-space noise under dither-space texture, a power of two (G§4)",
    ),
    (
        "azimuth_count",
        "expected 1..=64 azimuth views",
        "Number of billboard azimuth views J per elevation (E§7)",
    ),
    (
        "azimuth_mode",
        "expected 0 (nearest) or 1 (blend)",
        "Billboard azimuth view (issue 30): nearest, blend",
    ),
    (
        "occlusion",
        "expected 0 (off), 1 (single) or 2 (two-phase)",
        "Occlusion culling against a depth pyramid (issue 31): off, single, two-phase",
    ),
    (
        "occluder_depth",
        "expected a finite distance in 0..=1e7 m",
        "Depth behind the nearest mesh tree within which mesh trees are occluders under occlusion single, metres",
    ),
    (
        "occlusion_order",
        "expected 0 (exact) or 1 (reorder)",
        "Pass order of occlusion culling (issue 31): exact, reorder",
    ),
    (
        "billboard_views",
        "expected 0 (elevation), 1 (octahedral) or 2 (hemi-octahedral)",
        "Views the billboard array holds (issue 32): elevation (E Alg. 3.1), octahedral, hemi-octahedral",
    ),
    (
        "octahedral_grid",
        "expected 2..=32 frames a side",
        "Side N of the octahedral impostor grid, N x N frames per mesh",
    ),
    (
        "octahedral_blend",
        "expected 0 (nearest) or 1 (blend)",
        "Octahedral impostor frames drawn (issue 32): nearest, blend",
    ),
    (
        "far_lod",
        "expected 0 (octant-sprite), 1 (octant-cube), 2 (hull) or 3 (impostor)",
        "Far level of whole nodes under lod-levels 3 (issue 32): octant-sprite (G§2.3 sprite), octant-cube (G§2.3 cube), hull (E§7 batch hull), impostor (C§4.6.3 hierarchical impostor)",
    ),
    (
        "far_start",
        "expected a finite distance in 0..=1e7 m",
        "View depth from which a whole node may go far, metres (issue 32)",
    ),
    (
        "far_pixels",
        "expected a finite area in 0..=1e9 pixels",
        "Screen area under which a node goes far, pixels (C§4.6.3 metric on its box)",
    ),
    (
        "cluster_size",
        "expected 1..=12 cells per axis",
        "Cells per axis of a node's far level (G§2.4 clusterSize, cs^3 cells)",
    ),
    (
        "parent_rule",
        "expected 0 (average) or 1 (composite)",
        "How interior nodes' far cells come from their children (G§2.2): average (G§2.2), composite (beyond the seed)",
    ),
    (
        "octahedral_depth",
        "expected 0 (off) or 1 (on)",
        "Depth channel of octahedral impostors for the blend (issue 32): off, on",
    ),
    (
        "lod1",
        "expected 0 (billboard) or 1 (points)",
        "What a tree is drawn as past the mesh level (issue 33): billboard (E§3.3), points (C§4.4)",
    ),
    (
        "point_select",
        "expected 0 (interval) or 1 (cut)",
        "Which records of a tree's point hierarchy are drawn under lod1 points: interval (C§4.6.3), cut (ours, hole-free)",
    ),
    (
        "point_detail",
        "expected 0 (extra-high), 1 (high), 2 (normal), 3 (low) or 4 (extra-low)",
        "Point selection's screen areas under lod1 points: extra-high (C Table 5.2), high (C Table 5.2), normal (C Table 5.2), low (C Table 5.2), extra-low (C Table 5.2)",
    ),
    (
        "point_count",
        "expected 1..=4096 points per mesh",
        "Points placed per mesh under lod1 points (C§4.4.4 N_pts)",
    ),
    (
        "impostor_pixels",
        "expected 8..=256 pixels",
        "Side of a hierarchical impostor's tile under far-lod impostor, pixels (C§4.6.3 ImpostorWidth)",
    ),
    (
        "impostor_tiles",
        "expected 1..=4096 tiles",
        "Tiles of the impostor atlas under far-lod impostor (C§4.6.3 ImpostorTextureWidth)",
    ),
    (
        "impostor_min_distance",
        "expected a finite distance in 0..=1e7 m",
        "Least distance from the eye to a node's box for an impostor, metres (C§4.6.3 ImpostorMinimalDistance)",
    ),
    (
        "impostor_max_depth",
        "expected 0..=32 levels",
        "Deepest hierarchy level that may be impostored, root 0 (C§4.6.3 ImpostorHierarchyMaxDepth)",
    ),
    (
        "impostor_update_interval",
        "expected 1..=1048576 frames",
        "Frames between two impostor plans (C§4.6.3 ImpostorUpdateInterval)",
    ),
    (
        "impostor_refresh_interval",
        "expected 1..=1048576 frames",
        "Frames between two impostor refresh steps (C§4.6.3 ImpostorRefreshInterval)",
    ),
    (
        "impostor_refresh_number",
        "expected 0..=4096 impostors",
        "Impostors re-rendered per refresh step, round robin (C§4.6.3 ImpostorRefreshNumber)",
    ),
    (
        "point_grid",
        "expected 1..=10 cells per axis",
        "Grid a mesh's points are split by under lod1 points, g^3 cells (C§4.4.3 GridSizeX/Y/Z)",
    ),
];

#[test]
fn every_reason_and_help_is_as_pinned() {
    assert_eq!(
        PARAMS.len(),
        PINNED.len(),
        "a parameter was added: pin its texts"
    );
    for (spec, (name, reason, help)) in PARAMS.iter().zip(PINNED) {
        assert_eq!(spec.name, name);
        assert_eq!(spec.reason(), reason, "{name}: reason");
        assert_eq!(spec.help(), help, "{name}: help");
    }
}

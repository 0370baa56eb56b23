//! The reference frames that classify threshold-ambiguous pixels (`crate::image_compare` module
//! docs): the frame with the alpha-test cutoff moved by each of
//! `±image_compare::ALPHA_TEST_SHIFTS`, the frame under each implicit-LOD model of
//! `image_compare::LOD_RULES` (what a conforming adapter's other λ draws), and the baselines'
//! twins of the former. They are reference frames, not GPU ones: every parity judge of a GPU
//! frame draws them beside it.

use forestlod_reference::baselines::{Proxy, render_primitive_shifted, render_vegetation};
use forestlod_reference::pipeline::Prepared;
use forestlod_reference::raster::RenderTarget;
use forestlod_shared::{Camera, Params};

use crate::image_compare::Images;
use crate::stage::images_of;

/// The reference frames with the alpha-test cutoff moved by each of
/// `±image_compare::ALPHA_TEST_SHIFTS`, then the frames under each implicit-LOD model of
/// `image_compare::LOD_RULES`: the alternatives that classify threshold-ambiguous pixels
/// (`image_compare` module docs). The cutoffs are drawn together (`Prepared::render_cutoffs`:
/// one selection, one setup and one walk for all, each frame its own draw's bit for bit), the
/// models after them (`Prepared::render_lod_rules`).
pub fn alpha_test_alternatives(
    prepared: &Prepared,
    camera: &Camera,
    params: &Params,
) -> Vec<Images> {
    let cutoffs: Vec<f32> = cutoff_shifted(params, |p| p.alpha_cutoff);
    prepared
        .render_cutoffs(camera, params, &cutoffs, None)
        .expect("reference render")
        .into_iter()
        .chain(
            prepared
                .render_lod_rules(camera, params, &crate::image_compare::LOD_RULES, None)
                .expect("reference render"),
        )
        .map(|drawn| moved_images(drawn.target))
        .collect()
}

/// [`alpha_test_alternatives`] of one frame of a camera path under hierarchical impostors
/// (issue 33 item 2): the selection and the draw read `far`, the frame's impostor state
/// (`ImpostorCache::level`), in place of the prepared far level.
pub fn alpha_test_alternatives_on(
    prepared: &Prepared,
    far: &forestlod_shared::FarLevel,
    camera: &Camera,
    params: &Params,
) -> Vec<Images> {
    let cutoffs: Vec<f32> = cutoff_shifted(params, |p| p.alpha_cutoff);
    prepared
        .render_cutoffs_on(Some(far), camera, params, &cutoffs, None)
        .expect("reference render")
        .into_iter()
        .chain(
            prepared
                .render_lod_rules_on(
                    Some(far),
                    camera,
                    params,
                    &crate::image_compare::LOD_RULES,
                    None,
                )
                .expect("reference render"),
        )
        .map(|drawn| moved_images(drawn.target))
        .collect()
}

/// [`alpha_test_alternatives`] drawn only at `pixels` (`image_compare::alternative_pixels` of
/// the two frames to compare; the rest of each alternative is sky and never read), the six
/// cutoffs sharing one selection and one setup (`Prepared::render_cutoffs`), then the LOD models:
/// the same comparison for a fraction of one frame's cost. None at all when no pixel needs one.
pub fn alpha_test_alternatives_at(
    prepared: &Prepared,
    camera: &Camera,
    params: &Params,
    pixels: &[bool],
) -> Vec<Images> {
    if !pixels.contains(&true) {
        return Vec::new();
    }
    let cutoffs: Vec<f32> = cutoff_shifted(params, |p| p.alpha_cutoff);
    prepared
        .render_cutoffs(camera, params, &cutoffs, Some(pixels.to_vec()))
        .expect("reference render")
        .into_iter()
        .chain(
            prepared
                .render_lod_rules(
                    camera,
                    params,
                    &crate::image_compare::LOD_RULES,
                    Some(pixels.to_vec()),
                )
                .expect("reference render"),
        )
        .map(|drawn| moved_images(drawn.target))
        .collect()
}

/// The reference frames with the texture-space noise level's `ρ²` multiplied by `1 ∓ s` for
/// each `s` of `image_compare::NOISE_RHO2_SHIFTS` (`reference::draw::draw_frame_noise_scaled`):
/// the alternatives that classify the pixels whose noise level a quad's derivatives decide
/// within the twins' rounding of a level boundary (issue 30, G§4; `shared/src/noise.rs`). Empty
/// unless the frame draws texture-space noise (`dither_space = texture`).
pub fn noise_level_alternatives(
    prepared: &Prepared,
    camera: &Camera,
    params: &Params,
) -> Vec<Images> {
    if params.dither_space != forestlod_shared::DitherSpace::Texture as u32 {
        return Vec::new();
    }
    camera.validate().expect("a valid camera");
    params.validate().expect("valid parameters");
    let (selection, refined) = prepared.select_refined(camera, params);
    let res = forestlod_reference::draw::DrawResources {
        indirection: refined
            .as_ref()
            .map_or(&prepared.batches.indirection, |r| &r.indirection),
        ..prepared.resources()
    };
    crate::image_compare::NOISE_RHO2_SHIFTS
        .iter()
        .flat_map(|&s| [1.0 - s, 1.0 + s])
        .map(|scale| {
            moved_images(
                forestlod_reference::draw::draw_frame_noise_scaled(
                    &res, &selection, camera, params, scale, None,
                )
                .target,
            )
        })
        .collect()
}

/// A target's buffers as [`Images`], moved, not copied.
fn moved_images(target: RenderTarget) -> Images {
    let (width, height) = (target.width(), target.height());
    let (color, depth, lod_id) = target.into_buffers();
    Images {
        width,
        height,
        color,
        depth,
        lod_id,
    }
}

/// `render` with the alpha-test cutoff moved by each of `±image_compare::ALPHA_TEST_SHIFTS`
/// (clamped to `0..=1`).
fn cutoff_shifted<T>(params: &Params, render: impl Fn(&Params) -> T) -> Vec<T> {
    crate::image_compare::ALPHA_TEST_SHIFTS
        .iter()
        .flat_map(|&d| [-d, d])
        .map(|d| {
            render(&Params {
                alpha_cutoff: (params.alpha_cutoff + d).clamp(0.0, 1.0),
                ..*params
            })
        })
        .collect()
}

/// The reference Vegetation frames with the alpha-test cutoff moved by each of
/// `±image_compare::ALPHA_TEST_SHIFTS` ([`alpha_test_alternatives`] for Vegetation).
pub fn vegetation_alternatives(
    prepared: &Prepared,
    spheres: &[([f32; 3], f32)],
    camera: &Camera,
    params: &Params,
) -> Vec<Images> {
    cutoff_shifted(params, |p| {
        images_of(&render_vegetation(prepared, spheres, camera, p).target)
    })
}

/// The reference Primitive frames with the ray cast's root tests moved by each of
/// `±image_compare::PRIMITIVE_DISC_SHIFTS` roundings (`Proxy::intersect`): the
/// alternatives that classify the pixels a rounding of the discriminant decides.
pub fn primitive_alternatives(
    prepared: &Prepared,
    spheres: &[([f32; 3], f32)],
    proxies: &[Proxy],
    camera: &Camera,
    params: &Params,
) -> Vec<Images> {
    crate::image_compare::PRIMITIVE_DISC_SHIFTS
        .iter()
        .flat_map(|&d| [-d, d])
        .map(|d| {
            images_of(
                &render_primitive_shifted(prepared, spheres, proxies, camera, params, d).target,
            )
        })
        .collect()
}

//! Legends for the images the main job writes, so they read without the README: a strip appended
//! below the image (the canvas grows; the frame's pixels are untouched), drawn with the public-domain
//! `font8x8` bitmap font.
//!
//! - `lod.png`, `gpu_lod.png`: the LOD colours of E Fig. 3.1 ([`with_lod_legend`]);
//! - `parity_classes.png`: the colour classes of the parity verdict ([`with_class_legend`]:
//!   match, match within the ±1 px window, ambiguous (edge, alpha-test threshold or depth tie),
//!   mismatch);
//! - `diff.png`: `max |GPU - reference|` over R, G, B through a colour scale, with the scale bar
//!   ([`difference_heatmap`], [`with_diff_scale`]);
//! - the sweeps' frames (issue 35): the truth and each frame named ([`with_caption`]), the FLIP
//!   error maps with what they measure and their colour scale ([`with_flip_scale`]), the LOD ids
//!   with their colours ([`with_lod_legend`]).
//!
//! The images the golden and parity tests compare come from other functions
//! (`forestlod_reference::output::lod_id_image`, `forestlod_harness::image_compare::class_image`);
//! these only extend copies of them.

use forestlod_harness::image_compare::CLASS_COLORS;
use forestlod_reference::draw::{
    LOD_ID_BACKGROUND, LOD_ID_BILLBOARD, LOD_ID_FAR, LOD_ID_MESH, LOD_ID_TERRAIN,
    LOD_ID_TRANSITION, lod_id_color,
};
use forestlod_reference::texture::Rgba8Image;

const STRIP_BACKGROUND: [u8; 4] = [40, 40, 44, 255];
const TEXT: [u8; 4] = [235, 235, 235, 255];
const OUTLINE: [u8; 4] = [160, 160, 160, 255];

/// Font pixels per bitmap pixel: 2 on images at least 640 wide, else 1.
fn text_scale(width: u32) -> u32 {
    if width >= 640 { 2 } else { 1 }
}

fn fill(img: &mut Rgba8Image, x: u32, y: u32, w: u32, h: u32, c: [u8; 4]) {
    for yy in y..(y + h).min(img.height) {
        for xx in x..(x + w).min(img.width) {
            img.texels[(yy * img.width + xx) as usize] = c;
        }
    }
}

fn outline(img: &mut Rgba8Image, x: u32, y: u32, w: u32, h: u32, c: [u8; 4]) {
    fill(img, x, y, w, 1, c);
    fill(img, x, y + h - 1, w, 1, c);
    fill(img, x, y, 1, h, c);
    fill(img, x + w - 1, y, 1, h, c);
}

/// Draws `text` with its top-left at `(x, y)`; returns the x after it.
fn text(img: &mut Rgba8Image, s: &str, x: u32, y: u32, scale: u32, c: [u8; 4]) -> u32 {
    let mut pen = x;
    for ch in s.chars() {
        let code = if (ch as u32) < 128 {
            ch as usize
        } else {
            b'?' as usize
        };
        let glyph = font8x8::legacy::BASIC_LEGACY[code];
        for (row, bits) in glyph.iter().enumerate() {
            for col in 0..8u32 {
                if bits & (1 << col) != 0 {
                    fill(
                        img,
                        pen + col * scale,
                        y + row as u32 * scale,
                        scale,
                        scale,
                        c,
                    );
                }
            }
        }
        pen += 8 * scale;
    }
    pen
}

fn text_width(s: &str, scale: u32) -> u32 {
    s.chars().count() as u32 * 8 * scale
}

/// `image` with `strip_height` rows appended below (and columns on the right when the legend is
/// wider than the image), the new area filled with the strip background.
fn extend(image: &Rgba8Image, min_width: u32, strip_height: u32) -> Rgba8Image {
    let width = image.width.max(min_width);
    let height = image.height + strip_height;
    let mut out = Rgba8Image {
        width,
        height,
        texels: vec![STRIP_BACKGROUND; (width * height) as usize],
    };
    for y in 0..image.height {
        let src = (y * image.width) as usize;
        let dst = (y * width) as usize;
        out.texels[dst..dst + image.width as usize]
            .copy_from_slice(&image.texels[src..src + image.width as usize]);
    }
    out
}

/// Appends a strip of colour swatches and their labels below `image`, after a title.
pub fn with_swatch_legend(
    image: &Rgba8Image,
    title: &str,
    items: &[([u8; 4], &str)],
) -> Rgba8Image {
    let s = text_scale(image.width);
    let pad = 4 * s;
    let swatch = 8 * s;
    let gap = 12 * s;
    let widths: Vec<u32> = items
        .iter()
        .map(|(_, label)| swatch + pad + text_width(label, s))
        .collect();
    let total = text_width(title, s) + gap + widths.iter().sum::<u32>() + gap * items.len() as u32;
    let mut out = extend(image, total + 2 * pad, swatch + 2 * pad);
    let y = image.height + pad;
    let mut x = text(&mut out, title, pad, y, s, TEXT) + gap;
    for ((color, label), w) in items.iter().zip(&widths) {
        fill(&mut out, x, y, swatch, swatch, *color);
        outline(&mut out, x, y, swatch, swatch, OUTLINE);
        text(&mut out, label, x + swatch + pad, y, s, TEXT);
        x += w + gap;
    }
    out
}

/// `lod.png` with the LOD colours named (E Fig. 3.1).
pub fn with_lod_legend(image: &Rgba8Image) -> Rgba8Image {
    with_swatch_legend(
        image,
        "LOD:",
        &[
            (lod_id_color(LOD_ID_MESH), "LOD0 mesh"),
            (lod_id_color(LOD_ID_BILLBOARD), "LOD1 billboard"),
            (lod_id_color(LOD_ID_TRANSITION), "transition band"),
            (lod_id_color(LOD_ID_FAR), "far"),
            (lod_id_color(LOD_ID_TERRAIN), "terrain"),
            (lod_id_color(LOD_ID_BACKGROUND), "sky"),
        ],
    )
}

/// `parity_classes.png` with the colour classes named.
pub fn with_class_legend(image: &Rgba8Image) -> Rgba8Image {
    with_swatch_legend(
        image,
        "GPU colour vs reference:",
        &[
            (CLASS_COLORS[0], "match"),
            (CLASS_COLORS[1], "match within 1 px"),
            (CLASS_COLORS[2], "ambiguous"),
            (CLASS_COLORS[3], "mismatch"),
        ],
    )
}

/// Differences at or above this many 8-bit levels take the top colour of the diff scale.
pub const DIFF_SCALE_MAX: u8 = 32;

/// Stops of the diff colour scale (black, purple, red, orange, pale yellow), evenly spaced.
const SCALE_STOPS: [[f32; 3]; 5] = [
    [0.0, 0.0, 0.0],
    [90.0, 20.0, 140.0],
    [200.0, 50.0, 80.0],
    [250.0, 150.0, 20.0],
    [255.0, 255.0, 170.0],
];

/// The scale's colour at `t` in 0..=1.
fn scale_color(t: f32) -> [u8; 4] {
    let t = t.clamp(0.0, 1.0) * (SCALE_STOPS.len() - 1) as f32;
    let i = (t.floor() as usize).min(SCALE_STOPS.len() - 2);
    let f = t - i as f32;
    let (a, b) = (SCALE_STOPS[i], SCALE_STOPS[i + 1]);
    let c = |k: usize| (a[k] + (b[k] - a[k]) * f).round() as u8;
    [c(0), c(1), c(2), 255]
}

/// The colour of a difference of `d` levels: 0 is black, [`DIFF_SCALE_MAX`] and above the top.
pub fn diff_color(d: u8) -> [u8; 4] {
    scale_color(d as f32 / DIFF_SCALE_MAX as f32)
}

/// `max |a - b|` over R, G and B per pixel, through the diff colour scale.
pub fn difference_heatmap(width: u32, height: u32, a: &[[u8; 4]], b: &[[u8; 4]]) -> Rgba8Image {
    Rgba8Image {
        width,
        height,
        texels: a
            .iter()
            .zip(b)
            .map(|(x, y)| diff_color((0..3).map(|c| x[c].abs_diff(y[c])).max().unwrap_or(0)))
            .collect(),
    }
}

/// Appends the diff scale bar below `image`, labelled in 8-bit levels.
pub fn with_diff_scale(image: &Rgba8Image) -> Rgba8Image {
    let s = text_scale(image.width);
    let pad = 4 * s;
    let title = "max abs(GPU - reference) over R,G,B, 8-bit levels:";
    let bar_w = 128 * s;
    let label_h = 8 * s;
    let total = text_width(title, s) + 3 * pad + bar_w + text_width(">=32", s);
    let mut out = extend(image, total + 2 * pad, 2 * label_h + 3 * pad);
    let y = image.height + pad;
    let x0 = text(&mut out, title, pad, y, s, TEXT) + 2 * pad;
    for i in 0..bar_w {
        let c = scale_color(i as f32 / (bar_w - 1) as f32);
        fill(&mut out, x0 + i, y, 1, label_h, c);
    }
    outline(&mut out, x0, y, bar_w, label_h, OUTLINE);
    let ticks = DIFF_SCALE_MAX as u32 / 4;
    for v in (0..=DIFF_SCALE_MAX as u32).step_by(ticks as usize) {
        let tx = x0 + (v * (bar_w - 1)) / DIFF_SCALE_MAX as u32;
        fill(&mut out, tx, y + label_h, 1, pad, OUTLINE);
        let label = if v == DIFF_SCALE_MAX as u32 {
            format!(">={v}")
        } else {
            v.to_string()
        };
        let lx = tx.saturating_sub(text_width(&label, s) / 2);
        text(&mut out, &label, lx, y + label_h + pad, s, TEXT);
    }
    out
}

/// Appends one line of text below `image`: what the image is (issue 35: every image people look
/// at says what it shows).
pub fn with_caption(image: &Rgba8Image, caption: &str) -> Rgba8Image {
    let s = text_scale(image.width);
    let pad = 4 * s;
    let mut out = extend(image, text_width(caption, s) + 2 * pad, 8 * s + 2 * pad);
    text(&mut out, caption, pad, image.height + pad, s, TEXT);
    out
}

/// Appends what a FLIP error map shows (`title`) and its colour scale below it: FLIP's magma
/// colours from 0 (black, no error) to 1 ([`crate::metrics::error_image`]), ticks at 0, 0.5, 1.
pub fn with_flip_scale(image: &Rgba8Image, title: &str) -> Rgba8Image {
    let s = text_scale(image.width);
    let pad = 4 * s;
    let line = 8 * s;
    let bar_w = image.width.saturating_sub(2 * pad).clamp(64 * s, 256 * s);
    let width = text_width(title, s).max(bar_w + text_width("1", s)) + 2 * pad;
    let mut out = extend(image, width, 3 * line + 4 * pad);
    let y = image.height + pad;
    text(&mut out, title, pad, y, s, TEXT);
    let by = y + line + pad;
    let magma = crate::metrics::error_image(
        &(0..bar_w)
            .map(|i| i as f32 / (bar_w - 1) as f32)
            .collect::<Vec<_>>(),
        bar_w,
        1,
    );
    for (i, c) in magma.texels.iter().enumerate() {
        fill(&mut out, pad + i as u32, by, 1, line, *c);
    }
    outline(&mut out, pad, by, bar_w, line, OUTLINE);
    for (v, label) in [(0, "0"), (1, "0.5"), (2, "1")] {
        let tx = pad + v * (bar_w - 1) / 2;
        fill(&mut out, tx, by + line, 1, pad, OUTLINE);
        let lx = tx
            .saturating_sub(text_width(label, s) / 2)
            .min(out.width.saturating_sub(text_width(label, s)));
        text(&mut out, label, lx, by + line + pad, s, TEXT);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn legends_keep_the_frame_and_append_below() {
        let img = Rgba8Image::new(40, 30, [1, 2, 3, 255]);
        for out in [
            with_lod_legend(&img),
            with_class_legend(&img),
            with_diff_scale(&img),
            with_caption(&img, "ground truth"),
            with_flip_scale(&img, "FLIP vs truth"),
        ] {
            assert!(out.height > img.height);
            assert!(out.width >= img.width);
            for y in 0..img.height {
                for x in 0..img.width {
                    assert_eq!(out.texels[(y * out.width + x) as usize], [1, 2, 3, 255]);
                }
            }
            // Some text was drawn in the strip.
            assert!(out.texels.contains(&TEXT));
        }
    }

    #[test]
    fn diff_scale_is_black_at_zero_and_saturates() {
        assert_eq!(diff_color(0), [0, 0, 0, 255]);
        assert_eq!(diff_color(DIFF_SCALE_MAX), diff_color(255));
        assert_ne!(diff_color(1), diff_color(0));
        let a = [[10, 10, 10, 255], [0, 0, 0, 255]];
        let b = [[10, 10, 10, 255], [0, 40, 0, 255]];
        let h = difference_heatmap(2, 1, &a, &b);
        assert_eq!(h.texels[0], [0, 0, 0, 255]);
        assert_eq!(h.texels[1], diff_color(40));
    }
}

//! Fuzzes the PNG texture decoder (`decode_png_texture`): no input may panic or allocate beyond the
//! declared-size limit, and an accepted texture is square RGBA8 with a power-of-two side of at most
//! 4096 and exactly `width * height` texels.
#![no_main]

use forestlod_reference::scene::load::{MAX_TEXTURE_SIDE, decode_png_texture};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(t) = decode_png_texture(data, "fuzz.png") {
        assert!(t.width.is_power_of_two() && t.width <= MAX_TEXTURE_SIDE);
        assert_eq!(t.width, t.height);
        assert_eq!(t.texels.len(), (t.width * t.height) as usize);
    }
});

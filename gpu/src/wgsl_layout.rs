//! Test support (compiled only into tests): naga validation of the WGSL modules and reflection of
//! their struct layouts against the Rust `Pod` twins. The crate's unit tests use it as
//! `crate::wgsl_layout` and `gpu/tests/layout.rs` includes this very file, so every layout check
//! (SPEC §8: a drifting field fails here rather than as garbage in a parity test) is made one way.
//! naga's offsets are the ones wgpu's backends use.

#![allow(dead_code, reason = "each test crate uses its own part")]

/// A Rust struct's layout: `(field, offset)` in declaration order, and its size.
#[derive(Clone, Debug)]
pub struct RustLayout {
    /// The type's name, which its WGSL twin shares.
    pub name: &'static str,
    /// `(field, offset_of!)` in declaration order.
    pub fields: Vec<(&'static str, usize)>,
    /// `size_of`.
    pub size: usize,
}

/// The [`RustLayout`] of `Type { field, … }` (every field, in declaration order).
macro_rules! rust_layout {
    ($ty:ident { $($field:ident),* $(,)? }) => {
        $crate::wgsl_layout::RustLayout {
            name: stringify!($ty),
            fields: vec![$((stringify!($field), ::core::mem::offset_of!($ty, $field))),*],
            size: ::core::mem::size_of::<$ty>(),
        }
    };
}
pub(crate) use rust_layout;

/// Parses and validates a module with naga (default capabilities); returns it for reflection.
pub fn validate(source: &str) -> naga::Module {
    validate_with(source, naga::valid::Capabilities::default())
}

/// [`validate`] with the capabilities `capabilities`.
pub fn validate_with(source: &str, capabilities: naga::valid::Capabilities) -> naga::Module {
    let module = naga::front::wgsl::parse_str(source)
        .unwrap_or_else(|e| panic!("WGSL parse error:\n{}", e.emit_to_string(source)));
    naga::valid::Validator::new(naga::valid::ValidationFlags::all(), capabilities)
        .validate(&module)
        .unwrap_or_else(|e| panic!("WGSL validation error:\n{}", e.emit_to_string(source)));
    module
}

/// `(member, offset)` list and span of the WGSL struct `name`, if the module declares it.
pub fn wgsl_layout(module: &naga::Module, name: &str) -> Option<(Vec<(String, u32)>, u32)> {
    module.types.iter().find_map(|(_, ty)| match &ty.inner {
        naga::TypeInner::Struct { members, span } if ty.name.as_deref() == Some(name) => Some((
            members
                .iter()
                .map(|m| (m.name.clone().unwrap_or_default(), m.offset))
                .collect(),
            *span,
        )),
        _ => None,
    })
}

/// Asserts that the WGSL struct named like `rust` has exactly its members, in order, at its
/// offsets, and its size.
pub fn assert_layout(module: &naga::Module, rust: &RustLayout) {
    let (members, span) = wgsl_layout(module, rust.name)
        .unwrap_or_else(|| panic!("WGSL has no struct {}", rust.name));
    let wgsl: Vec<(&str, usize)> = members
        .iter()
        .map(|(n, o)| (n.as_str(), *o as usize))
        .collect();
    assert_eq!(
        wgsl, rust.fields,
        "struct {}: WGSL members/offsets (left) differ from Rust (right)",
        rust.name
    );
    assert_eq!(
        span as usize, rust.size,
        "struct {}: WGSL size differs from Rust",
        rust.name
    );
}

/// Asserts that the WGSL struct `name` has `rust`'s offsets and size (member names may differ).
pub fn assert_offsets(module: &naga::Module, name: &str, rust: &RustLayout) {
    let (members, span) =
        wgsl_layout(module, name).unwrap_or_else(|| panic!("WGSL has no struct {name}"));
    let wgsl: Vec<usize> = members.iter().map(|(_, o)| *o as usize).collect();
    let offsets: Vec<usize> = rust.fields.iter().map(|(_, o)| *o).collect();
    assert_eq!(
        wgsl, offsets,
        "struct {name}: WGSL offsets differ from {}'s",
        rust.name
    );
    assert_eq!(
        span as usize, rust.size,
        "struct {name}: WGSL size differs from Rust"
    );
}

/// `module`'s `ViewUniform` and `FrustumPlanes` have the layout of
/// `forestlod_shared::{ViewUniform, FrustumPlanes}` (the stage uniforms embed them).
pub fn assert_view_uniform(module: &naga::Module) {
    use forestlod_shared::FrustumPlanes;
    assert_layout(module, &rust_layout!(FrustumPlanes { planes }));
    assert_layout(module, &view_uniform_layout());
}

/// `forestlod_shared::ViewUniform`'s layout.
pub fn view_uniform_layout() -> RustLayout {
    use forestlod_shared::ViewUniform;
    rust_layout!(ViewUniform {
        frustum,
        eye,
        fade_start,
        forward,
        fade_end,
        draw_distance,
        lod_levels,
        metric,
        metric_factor,
        band_ratio,
        subset_mode,
        subset_distance,
        subset_min
    })
}

//! glTF 2.0 tree meshes, `.gltf` (JSON) or `.glb` (binary) (module docs, "Meshes";
//! [`parse_gltf_mesh`] for what is accepted): one mesh of triangle-list primitives, merged,
//! untransformed, converted from its up axis (+Y by default) to Z up. Buffers come from the
//! GLB's binary chunk, a base64 `data:` URI or a file beside the glTF file, confined like every
//! named file ([`GltfBuffers`]). Every accessor read is bounds-checked; every failure names the
//! file, the mesh/primitive/attribute and the value.
//!
//! Issue 28 (hostile input):
//! - **GLB headers are checked here** before the `gltf` crate reads the file ([`check_glb`]): the
//!   crate reports a wrong magic as a JSON parse error, a declared length past the end as "could
//!   not completely read the object", subtracts the header from a declared length below 12
//!   without a check, and accepts a file longer than declared. Each header field (magic,
//!   version, length) and each chunk header (type, length) gets an error naming the field, the
//!   value found and the value expected.
//! - **Buffer URIs are percent-decoded**, as glTF 2.0 requires (its URIs are RFC 3986
//!   references: a buffer file `my buffer.bin` is written `my%20buffer.bin`), by
//!   [`buffer_path`]; a `%` not followed by two hex digits, a decoded NUL or non-UTF-8 bytes, a
//!   query or fragment, and a scheme other than `data:` are errors naming the field. The
//!   folder confinement applies to the decoded path, so `%2e%2e%2f` cannot leave the folder.
//! - `data:` URIs are decoded in memory as before; they are bounded by the glTF file's own
//!   limit ([`MAX_MESH_FILE_BYTES`]), since they are part of it.
//!
//! Depends on `paths`, `diagnostics`, `coords` and `png_texture`.

use std::path::Path;

use super::coords::UpAxis;
use super::diagnostics::cut_quoted;
use super::paths::{LoadOptions, MAX_MESH_FILE_BYTES, confine, label, read_limited, scene_folder};
use super::png_texture::load_png_texture;
use crate::InputError;
use crate::error::{cut, excerpt};
use crate::scene::{MAX_TREE_TRIANGLES, TreeMesh};
use crate::texture::Rgba8Image;

/// Where a glTF file's external buffers (`"uri": "tree.bin"`) are read from: `folder` (the glTF
/// file's), confined to `root` (the scene file's folder) unless `options` allow otherwise.
#[derive(Clone, Copy, Debug)]
pub struct GltfBuffers<'a> {
    /// The glTF file's folder; buffer URIs are relative to it.
    pub folder: &'a Path,
    /// The folder every file must lie under (the scene file's).
    pub root: &'a Path,
    /// Whether files outside `root` are allowed.
    pub options: &'a LoadOptions,
}

/// Loads a glTF 2.0 tree mesh (`.gltf` or `.glb`, [`parse_gltf_mesh`]) named `name` with the RGBA
/// PNG `texture`; `up` is the file's up axis (glTF's own is +Y). External buffers may lie
/// anywhere under the glTF file's folder.
pub fn load_gltf_mesh(
    name: &str,
    gltf: &Path,
    texture: &Path,
    up: UpAxis,
) -> Result<TreeMesh, InputError> {
    let bytes = read_limited(gltf, MAX_MESH_FILE_BYTES)?;
    let image = load_png_texture(texture)?;
    let folder = scene_folder(gltf);
    let options = LoadOptions::default();
    let buffers = GltfBuffers {
        folder,
        root: folder,
        options: &options,
    };
    parse_gltf_mesh(name, &bytes, &label(gltf), up, image, &buffers)
}

/// The GLB header's magic, `glTF` (glTF 2.0 §4.4.2).
const GLB_MAGIC: [u8; 4] = *b"glTF";
/// The GLB container version this loader reads.
const GLB_VERSION: u32 = 2;
/// Bytes of the GLB header: magic, version, length.
const GLB_HEADER_BYTES: usize = 12;
/// Bytes of a chunk header: length, type.
const GLB_CHUNK_HEADER_BYTES: usize = 8;
/// The first chunk's type: the JSON document.
const GLB_JSON: [u8; 4] = *b"JSON";
/// The second chunk's type, when there is one: the binary buffer.
const GLB_BIN: [u8; 4] = *b"BIN\0";

/// Four bytes as an error shows them: as text with non-printable bytes escaped, and as the
/// little-endian number the header holds.
fn tag(bytes: [u8; 4]) -> String {
    format!(
        "{} ({:#010x})",
        bytes.escape_ascii(),
        u32::from_le_bytes(bytes)
    )
}

fn u32_at(bytes: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]])
}

/// Whether `bytes` (of `file`) are read as a GLB: the name ends in `.glb`, or the bytes start
/// with the GLB magic (as the `gltf` crate decides).
fn is_glb(bytes: &[u8], file: &str) -> bool {
    bytes.starts_with(&GLB_MAGIC)
        || Path::new(file)
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("glb"))
}

/// Checks a GLB's header and chunk headers (glTF 2.0 §4.4, module docs): magic `glTF`, version
/// 2, a declared length equal to the file's size, a first chunk of type `JSON` whose length fits
/// the file, and, when more bytes follow, a chunk of type `BIN\0` whose length fits. Each error
/// names `file`, the field (`GLB header, magic`, `GLB chunk 0 (JSON), length`...), the value
/// found and the value expected.
fn check_glb(bytes: &[u8], file: &str) -> Result<(), InputError> {
    let err = |position: &str, value: String, reason: String| {
        InputError::new(file, position, value, reason)
    };
    if bytes.len() < GLB_HEADER_BYTES {
        return Err(err(
            "GLB header",
            format!("{} bytes", bytes.len()),
            format!(
                "expected the {GLB_HEADER_BYTES}-byte GLB header (magic, version, length): the file is truncated"
            ),
        ));
    }
    let magic = [bytes[0], bytes[1], bytes[2], bytes[3]];
    if magic != GLB_MAGIC {
        return Err(err(
            "GLB header, magic",
            tag(magic),
            format!(
                "expected {}: a .glb file starts with the binary glTF magic (a JSON glTF file ends in .gltf)",
                tag(GLB_MAGIC)
            ),
        ));
    }
    let version = u32_at(bytes, 4);
    if version != GLB_VERSION {
        return Err(err(
            "GLB header, version",
            version.to_string(),
            format!("expected {GLB_VERSION} (binary glTF 2.0)"),
        ));
    }
    let length = u32_at(bytes, 8) as usize;
    if length != bytes.len() {
        return Err(err(
            "GLB header, length",
            format!("{length} bytes"),
            format!(
                "expected the file's size, {} bytes: the file is {}",
                bytes.len(),
                if length > bytes.len() {
                    "truncated"
                } else {
                    "longer than its header says"
                }
            ),
        ));
    }
    let mut at = GLB_HEADER_BYTES;
    for (index, (want, name, what)) in [
        (GLB_JSON, "JSON", "the glTF JSON"),
        (GLB_BIN, "BIN", "the binary buffer"),
    ]
    .into_iter()
    .enumerate()
    {
        let left = bytes.len() - at;
        if index == 1 && left == 0 {
            break; // no binary chunk
        }
        let chunk = format!("GLB chunk {index} ({name})");
        if left < GLB_CHUNK_HEADER_BYTES {
            return Err(err(
                &format!("{chunk}, header"),
                format!("{left} bytes"),
                format!("expected an {GLB_CHUNK_HEADER_BYTES}-byte chunk header (length, type)"),
            ));
        }
        let ty = [bytes[at + 4], bytes[at + 5], bytes[at + 6], bytes[at + 7]];
        if ty != want {
            return Err(err(
                &format!("{chunk}, type"),
                tag(ty),
                format!("expected {}: chunk {index} holds {what}", tag(want)),
            ));
        }
        let chunk_length = u32_at(bytes, at) as usize;
        let room = left - GLB_CHUNK_HEADER_BYTES;
        if chunk_length > room {
            return Err(err(
                &format!("{chunk}, length"),
                format!("{chunk_length} bytes"),
                format!("expected at most the {room} bytes left in the file"),
            ));
        }
        at += GLB_CHUNK_HEADER_BYTES + chunk_length;
    }
    Ok(())
}

/// The path a relative buffer URI names (module docs): percent-decoded, as UTF-8. `at` is the
/// field (`buffer 0, uri`) errors name in `file`.
fn buffer_path(uri: &str, file: &str, at: &str) -> Result<String, InputError> {
    let err = |reason: String| InputError::new(file, at, uri, reason);
    // RFC 3986 §3.1: scheme = ALPHA *( ALPHA / DIGIT / "+" / "-" / "." ), then ':'.
    if let Some((scheme, _)) = uri.split_once(':')
        && scheme.starts_with(|c: char| c.is_ascii_alphabetic())
        && scheme
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '+' | '-' | '.'))
    {
        return Err(err(format!(
            "expected a file path relative to the glTF file, or a data: URI; a {scheme}: URI is not read"
        )));
    }
    if let Some(i) = uri.find(['?', '#']) {
        return Err(err(format!(
            "expected a file path: {:?} at character {i} starts a URI query or fragment (a file name holding it is written %3F or %23)",
            &uri[i..=i]
        )));
    }
    let raw = uri.as_bytes();
    if let Some(i) = raw.iter().enumerate().position(|(i, &b)| {
        b == b'%'
            && !(raw.get(i + 1).is_some_and(u8::is_ascii_hexdigit)
                && raw.get(i + 2).is_some_and(u8::is_ascii_hexdigit))
    }) {
        let shown: String = uri[i..].chars().take(3).collect();
        return Err(err(format!(
            "invalid percent-encoding {shown:?} at character {i}: expected % and two hex digits (a % in a file name is written %25)"
        )));
    }
    let decoded = percent_encoding::percent_decode_str(uri)
        .decode_utf8()
        .map_err(|e| err(format!("percent-decodes to bytes that are not UTF-8 ({e})")))?;
    if decoded.contains('\0') {
        return Err(err(
            "percent-decodes to a NUL byte, which no file name holds".into(),
        ));
    }
    if decoded.is_empty() {
        return Err(err("expected a file name".into()));
    }
    Ok(decoded.into_owned())
}

/// Decodes standard base64 (RFC 4648, `=` padding optional); `None` on any other character.
fn decode_base64(text: &str) -> Option<Vec<u8>> {
    let mut out = Vec::with_capacity(text.len() / 4 * 3);
    let (mut acc, mut bits) = (0u32, 0u32);
    let text = text.trim_end_matches('=');
    for c in text.bytes() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            _ => return None,
        } as u32;
        acc = (acc << 6) | v;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    Some(out)
}

/// Parses glTF 2.0 `bytes` (JSON `.gltf` or binary `.glb`; `file` names them in errors) into a
/// tree mesh with `texture`, the way a tree needs it and no further:
/// - exactly one mesh; every primitive of it is merged; each must be a triangle list
///   (`mode` 4) with `POSITION` (float VEC3) and `TEXCOORD_0` (float, or normalized unsigned
///   byte/short VEC2), and optional `indices` (unsigned byte/short/int); sparse accessors are not
///   supported;
/// - a node that uses the mesh must have the identity transform (apply transforms before
///   export): the mesh is taken in its own coordinates, converted from `up` (glTF's +Y by
///   default) to Z up;
/// - a `.glb` file (or one starting with the GLB magic) has a valid GLB header and chunk
///   headers ([`check_glb`]);
/// - buffers come from the GLB's binary chunk, a base64 `data:` URI, or a file relative to
///   the glTF file, its URI percent-decoded ([`buffer_path`], [`GltfBuffers`]);
/// - materials and the file's own images are ignored: the scene file's `texture` is the mesh's
///   texture (glTF's UV origin is the top-left, as [`TreeMesh::uvs`]).
///
/// Positions must be finite, indices in range, at most 19 triangles and 256 vertices; every
/// failure names the file, the mesh/primitive/attribute and the value.
pub fn parse_gltf_mesh(
    name: &str,
    bytes: &[u8],
    file: &str,
    up: UpAxis,
    texture: Rgba8Image,
    buffers: &GltfBuffers,
) -> Result<TreeMesh, InputError> {
    let err = |position: String, value: String, reason: String| {
        InputError::new(file, position, value, reason)
    };
    if is_glb(bytes, file) {
        check_glb(bytes, file)?;
    }
    let gltf = gltf::Gltf::from_slice(bytes).map_err(|e| {
        let message = e.to_string().replace(['\n', '\r'], " ");
        err(
            "file".into(),
            format!("{} bytes", bytes.len()),
            format!("invalid glTF 2.0: {}", cut_quoted(&message)),
        )
    })?;
    let document = &gltf.document;
    let meshes: Vec<gltf::Mesh> = document.meshes().collect();
    if meshes.len() != 1 {
        return Err(err(
            "meshes".into(),
            format!("{} meshes", meshes.len()),
            "expected exactly one mesh (a tree)".into(),
        ));
    }
    let gmesh = &meshes[0];
    for node in document.nodes() {
        if node.mesh().is_some() {
            let m = node.transform().matrix();
            let identity =
                (0..4).all(|c| (0..4).all(|r| m[c][r] == if c == r { 1.0 } else { 0.0 }));
            if !identity {
                let (t, r, sc) = node.transform().decomposed();
                return Err(err(
                    format!("node {}, transform", node.index()),
                    format!(
                        "translation {} {} {}, rotation {} {} {} {}, scale {} {} {}",
                        t[0], t[1], t[2], r[0], r[1], r[2], r[3], sc[0], sc[1], sc[2]
                    ),
                    "expected no transform on the mesh's node (apply transforms before export)"
                        .into(),
                ));
            }
        }
    }
    // Buffer contents, by buffer index.
    let mut data: Vec<Vec<u8>> = Vec::new();
    for buffer in document.buffers() {
        let at = format!("buffer {}", buffer.index());
        let bytes = match buffer.source() {
            gltf::buffer::Source::Bin => gltf.blob.clone().ok_or_else(|| {
                err(
                    at.clone(),
                    "no binary chunk".into(),
                    "expected the GLB's binary chunk (a .gltf file needs a uri)".into(),
                )
            })?,
            gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                let payload = uri.split_once(";base64,").map(|(_, b)| b).ok_or_else(|| {
                    err(
                        at.clone(),
                        cut(uri),
                        "expected a base64 data URI (data:application/octet-stream;base64,...)"
                            .into(),
                    )
                })?;
                decode_base64(payload).ok_or_else(|| {
                    err(
                        at.clone(),
                        cut(uri),
                        "invalid base64 in the data URI".into(),
                    )
                })?
            }
            gltf::buffer::Source::Uri(uri) => {
                let named = buffer_path(uri, file, &format!("{at}, uri"))?;
                let path = confine(
                    buffers.root,
                    buffers.folder.join(&named),
                    uri,
                    buffers.options,
                    file,
                    &format!("{at}, uri"),
                )?;
                read_limited(&path, MAX_MESH_FILE_BYTES)
                    .map_err(|e| e.within(format!("{file}: {at}, uri = {}", excerpt(uri))))?
            }
        };
        if bytes.len() < buffer.length() {
            return Err(err(
                at,
                format!("{} bytes", bytes.len()),
                format!("expected byteLength {} bytes of data", buffer.length()),
            ));
        }
        data.push(bytes);
    }
    let mut mesh = TreeMesh::new(name, texture);
    let mesh_at = format!("mesh {}", gmesh.index());
    for primitive in gmesh.primitives() {
        let prim_at = format!("{mesh_at}, primitive {}", primitive.index());
        if primitive.mode() != gltf::mesh::Mode::Triangles {
            return Err(err(
                format!("{prim_at}, mode"),
                match primitive.mode() {
                    gltf::mesh::Mode::Points => "POINTS (0)",
                    gltf::mesh::Mode::Lines => "LINES (1)",
                    gltf::mesh::Mode::LineLoop => "LINE_LOOP (2)",
                    gltf::mesh::Mode::LineStrip => "LINE_STRIP (3)",
                    gltf::mesh::Mode::Triangles => "TRIANGLES (4)",
                    gltf::mesh::Mode::TriangleStrip => "TRIANGLE_STRIP (5)",
                    gltf::mesh::Mode::TriangleFan => "TRIANGLE_FAN (6)",
                }
                .to_string(),
                "expected a triangle list (mode 4, TRIANGLES)".into(),
            ));
        }
        let base = mesh.positions.len();
        let positions = primitive.get(&gltf::Semantic::Positions).ok_or_else(|| {
            err(
                format!("{prim_at}, attributes"),
                "no POSITION".into(),
                "expected a POSITION attribute".into(),
            )
        })?;
        let uvs = primitive
            .get(&gltf::Semantic::TexCoords(0))
            .ok_or_else(|| {
                err(
                    format!("{prim_at}, attributes"),
                    "no TEXCOORD_0".into(),
                    "expected texture coordinates (TEXCOORD_0) for every vertex".into(),
                )
            })?;
        let count = positions.count();
        if base + count > forestlod_shared::MAX_MESH_VERTICES as usize {
            return Err(err(
                "vertex count".into(),
                (base + count).to_string(),
                format!(
                    "expected at most {} vertices per tree mesh",
                    forestlod_shared::MAX_MESH_VERTICES
                ),
            ));
        }
        if uvs.count() != count {
            return Err(err(
                format!("{prim_at}, TEXCOORD_0"),
                format!("{} texture coordinates for {count} vertices", uvs.count()),
                "expected one texture coordinate per vertex".into(),
            ));
        }
        // The accessor's values, `width` per element, each element finite.
        let read_finite =
            |accessor: &gltf::Accessor, attribute: &str, usage, width, reason: &str| {
                let values = read_accessor(
                    accessor,
                    &data,
                    file,
                    &format!("{prim_at}, {attribute}"),
                    usage,
                )?;
                if let Some((i, v)) = values
                    .chunks_exact(width)
                    .enumerate()
                    .find(|(_, v)| v.iter().any(|c| !c.is_finite()))
                {
                    let shown: Vec<String> = v.iter().map(f64::to_string).collect();
                    return Err(err(
                        format!("{prim_at}, {attribute} element {i}"),
                        format!("({})", shown.join(", ")),
                        reason.into(),
                    ));
                }
                Ok(values)
            };
        let p = read_finite(
            &positions,
            "POSITION",
            AccessorUse::Position,
            3,
            "expected finite coordinates",
        )?;
        for v in p.chunks_exact(3) {
            mesh.positions
                .push(up.to_z_up([v[0] as f32, v[1] as f32, v[2] as f32]));
        }
        let t = read_finite(
            &uvs,
            "TEXCOORD_0",
            AccessorUse::TexCoord,
            2,
            "expected finite texture coordinates",
        )?;
        for uv in t.chunks_exact(2) {
            mesh.uvs.push([uv[0] as f32, uv[1] as f32]);
        }
        let local: Vec<u32> = match primitive.indices() {
            Some(indices) => {
                if indices.count() > 3 * MAX_TREE_TRIANGLES {
                    return Err(err(
                        format!("{prim_at}, indices"),
                        format!("{} indices", indices.count()),
                        format!("expected at most {MAX_TREE_TRIANGLES} triangles per tree (E§3.1)"),
                    ));
                }
                read_accessor(
                    &indices,
                    &data,
                    file,
                    &format!("{prim_at}, indices"),
                    AccessorUse::Index,
                )?
                .into_iter()
                .map(|i| i as u32)
                .collect()
            }
            None => (0..count as u32).collect(),
        };
        if !local.len().is_multiple_of(3) {
            return Err(err(
                format!("{prim_at}, indices"),
                format!("{} indices", local.len()),
                "expected a multiple of 3 (a triangle list)".into(),
            ));
        }
        for (k, &i) in local.iter().enumerate() {
            if i as usize >= count {
                return Err(err(
                    format!("{prim_at}, indices element {k}"),
                    i.to_string(),
                    format!("index out of range ({count} vertices)"),
                ));
            }
            // base + i < MAX_MESH_VERTICES (checked above) fits in u32.
            mesh.indices.push(base as u32 + i);
        }
    }
    mesh.validate(file)?;
    Ok(mesh)
}

/// What an accessor is read as, which decides the types it may have.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum AccessorUse {
    /// `POSITION`: float VEC3.
    Position,
    /// `TEXCOORD_0`: VEC2 of float, or normalized unsigned byte or short.
    TexCoord,
    /// `indices`: SCALAR unsigned byte, short or int.
    Index,
}

/// Reads every component of `accessor` as `f64` (bounds-checked against the buffer data; no
/// arithmetic can overflow: counts are limited first).
fn read_accessor(
    accessor: &gltf::Accessor,
    data: &[Vec<u8>],
    file: &str,
    at: &str,
    usage: AccessorUse,
) -> Result<Vec<f64>, InputError> {
    use gltf::accessor::{DataType, Dimensions};
    let err = |value: String, reason: &str| InputError::new(file, at, value, reason);
    let (dims, ty, normalized) = (
        accessor.dimensions(),
        accessor.data_type(),
        accessor.normalized(),
    );
    let ok = match usage {
        AccessorUse::Position => dims == Dimensions::Vec3 && ty == DataType::F32,
        AccessorUse::TexCoord => {
            dims == Dimensions::Vec2
                && (ty == DataType::F32
                    || (normalized && matches!(ty, DataType::U8 | DataType::U16)))
        }
        AccessorUse::Index => {
            dims == Dimensions::Scalar && matches!(ty, DataType::U8 | DataType::U16 | DataType::U32)
        }
    };
    let kind = format!(
        "{}{} {}",
        if normalized { "normalized " } else { "" },
        match ty {
            DataType::I8 => "byte",
            DataType::U8 => "unsigned byte",
            DataType::I16 => "short",
            DataType::U16 => "unsigned short",
            DataType::U32 => "unsigned int",
            DataType::F32 => "float",
        },
        match dims {
            Dimensions::Scalar => "SCALAR",
            Dimensions::Vec2 => "VEC2",
            Dimensions::Vec3 => "VEC3",
            Dimensions::Vec4 => "VEC4",
            Dimensions::Mat2 => "MAT2",
            Dimensions::Mat3 => "MAT3",
            Dimensions::Mat4 => "MAT4",
        }
    );
    if !ok {
        let expected = match usage {
            AccessorUse::Position => "expected float VEC3 positions",
            AccessorUse::TexCoord => {
                "expected VEC2 texture coordinates of float, or normalized unsigned byte/short"
            }
            AccessorUse::Index => "expected unsigned byte, short or int indices",
        };
        return Err(err(kind, expected));
    }
    if accessor.sparse().is_some() {
        return Err(err("sparse".into(), "sparse accessors are not supported"));
    }
    let count = accessor.count();
    if count == 0 || count > 4 * forestlod_shared::MAX_MESH_VERTICES as usize {
        return Err(err(
            format!("count {count}"),
            "expected between 1 and a tree's few hundred elements",
        ));
    }
    let view = accessor.view().ok_or_else(|| {
        err(
            "no bufferView".into(),
            "expected an accessor with data (a bufferView)",
        )
    })?;
    let component = match ty {
        DataType::I8 | DataType::U8 => 1usize,
        DataType::I16 | DataType::U16 => 2,
        DataType::U32 | DataType::F32 => 4,
    };
    let width = dims.multiplicity();
    let element = component * width;
    let stride = view.stride().unwrap_or(element);
    if stride < element {
        return Err(err(
            format!("byteStride {stride}"),
            "expected a stride of at least one element",
        ));
    }
    let buffer = data
        .get(view.buffer().index())
        .map_or(&[][..], Vec::as_slice);
    let view_end = view.offset().checked_add(view.length());
    let Some(view_bytes) = view_end.and_then(|end| buffer.get(view.offset()..end)) else {
        return Err(err(
            format!(
                "bufferView {} bytes {}+{}",
                view.index(),
                view.offset(),
                view.length()
            ),
            "bufferView out of its buffer's data",
        ));
    };
    let needed = accessor
        .offset()
        .checked_add(stride * (count - 1) + element)
        .filter(|&end| end <= view_bytes.len());
    if needed.is_none() {
        return Err(err(
            format!(
                "byteOffset {} count {count} stride {stride}",
                accessor.offset()
            ),
            "accessor out of its bufferView",
        ));
    }
    let mut out = Vec::with_capacity(count * width);
    for i in 0..count {
        let start = accessor.offset() + i * stride;
        for c in 0..width {
            let b = &view_bytes[start + c * component..start + (c + 1) * component];
            let v = match ty {
                DataType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
                DataType::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
                DataType::U16 => {
                    let v = u16::from_le_bytes([b[0], b[1]]) as f64;
                    if normalized { v / 65535.0 } else { v }
                }
                DataType::U8 => {
                    let v = b[0] as f64;
                    if normalized { v / 255.0 } else { v }
                }
                // Excluded above.
                DataType::I8 | DataType::I16 => 0.0,
            };
            out.push(v);
        }
    }
    Ok(out)
}

//! Wavefront OBJ tree meshes (module docs, "Meshes"): parsed by `tobj` after a prescan that
//! gives every bad number or index its line, all objects and groups merged, polygons
//! triangulated in their plane ([`triangulate_polygon`]: convex ones as fans, concave ones by
//! ear clipping, degenerate ones refused), texture coordinates flipped from `v` up to the
//! top-left convention, positions converted to Z up. The result passes `TreeMesh::validate`.
//!
//! Depends on `paths`, `diagnostics`, `coords` and `png_texture`.

use std::io::Cursor;
use std::path::Path;

use super::coords::{UpAxis, bounding_box};
use super::diagnostics::utf8_error_line;
use super::paths::{MAX_MESH_FILE_BYTES, label, read_limited};
use super::png_texture::load_png_texture;
use crate::InputError;
use crate::error::excerpt;
use crate::scene::{MAX_TREE_TRIANGLES, TreeMesh};
use crate::texture::Rgba8Image;

/// Loads an OBJ tree mesh named `name` with the RGBA PNG `texture`; `up` is the OBJ's up axis.
/// Validated with [`TreeMesh::validate`] (at most 19 triangles, 256 vertices, finite values,
/// indices in range).
pub fn load_obj_mesh(
    name: &str,
    obj: &Path,
    texture: &Path,
    up: UpAxis,
) -> Result<TreeMesh, InputError> {
    let bytes = read_limited(obj, MAX_MESH_FILE_BYTES)?;
    let image = load_png_texture(texture)?;
    parse_obj_mesh(name, &bytes, &label(obj), up, image)
}

/// Parses OBJ `bytes` (`file` names them in errors) into a tree mesh with `texture`. Every object
/// and group is merged; points and lines are ignored; materials are ignored. Every vertex needs a
/// texture coordinate (`f v/vt`). Faces with more than three vertices are triangulated in their
/// plane ([`triangulate_polygon`]): convex ones as fans from their first vertex (as before),
/// concave ones by ear clipping; non-planar, self-intersecting and zero-area polygons are errors
/// naming the face's line.
pub fn parse_obj_mesh(
    name: &str,
    bytes: &[u8],
    file: &str,
    up: UpAxis,
    texture: Rgba8Image,
) -> Result<TreeMesh, InputError> {
    let text = std::str::from_utf8(bytes).map_err(|e| {
        InputError::new(
            file,
            format!("line {}", utf8_error_line(bytes, &e)),
            format!("byte {}", e.valid_up_to()),
            "expected UTF-8 text (OBJ)",
        )
    })?;
    let face_lines = prescan_obj(text, file)?;
    // tobj's optional `merging`/`reordering` features add fields: keep the struct update.
    // Faces are kept whole (`triangulate: false`): tobj would fan-triangulate concave polygons
    // wrongly. Vertices come out in the same order either way.
    #[allow(clippy::needless_update)]
    let options = tobj::LoadOptions {
        triangulate: false,
        single_index: true,
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    };
    let (models, _materials) =
        tobj::load_obj_buf(&mut Cursor::new(text.as_bytes()), &options, |_| {
            Err(tobj::LoadError::OpenFileFailed)
        })
        .map_err(|e| InputError::new(file, "file", "", format!("invalid OBJ: {e}")))?;
    let mut mesh = TreeMesh::new(name, texture);
    // Faces (of 3 or more vertices) seen so far, over all models: indexes `face_lines`.
    let mut face_number = 0usize;
    for model in &models {
        let m = &model.mesh;
        let count = m.positions.len() / 3;
        if m.texcoords.len() != 2 * count {
            return Err(InputError::new(
                file,
                format!("object {}", excerpt(&model.name)),
                format!(
                    "{} texture coordinates for {count} vertices",
                    m.texcoords.len() / 2
                ),
                "expected a texture coordinate for every vertex (faces as f v/vt)",
            ));
        }
        let base = mesh.positions.len();
        if base + count > forestlod_shared::MAX_MESH_VERTICES as usize {
            return Err(InputError::new(
                file,
                "vertex count",
                base + count,
                format!(
                    "expected at most {} vertices per tree mesh",
                    forestlod_shared::MAX_MESH_VERTICES
                ),
            ));
        }
        for (p, t) in m.positions.chunks_exact(3).zip(m.texcoords.chunks_exact(2)) {
            mesh.positions.push(up.to_z_up([p[0], p[1], p[2]]));
            mesh.uvs.push([t[0], 1.0 - t[1]]);
        }
        let mut next = 0usize;
        let mut face_in_model = 0usize;
        while next < m.indices.len() {
            let arity = if m.face_arities.is_empty() {
                3
            } else {
                match m.face_arities.get(face_in_model) {
                    Some(&a) => a as usize,
                    None => break,
                }
            };
            face_in_model += 1;
            let Some(face) = m.indices.get(next..next + arity) else {
                break;
            };
            next += arity;
            face_number += 1;
            let at = || match face_lines.get(face_number - 1) {
                Some(line) => format!("line {line}, face"),
                None => format!("face {face_number}"),
            };
            // base + index < MAX_MESH_VERTICES (checked above) fits in u32.
            let global = |k: usize| base as u32 + face[k];
            if arity == 3 {
                mesh.indices.extend([global(0), global(1), global(2)]);
                continue;
            }
            if arity > MAX_TREE_TRIANGLES + 2 {
                return Err(InputError::new(
                    file,
                    at(),
                    format!("{arity} vertices"),
                    format!(
                        "a polygon of {arity} vertices makes {} triangles: expected at most {MAX_TREE_TRIANGLES} triangles per tree (E§3.1)",
                        arity - 2
                    ),
                ));
            }
            let points: Vec<[f64; 3]> = face
                .iter()
                .map(|&i| {
                    let p = &m.positions[3 * i as usize..3 * i as usize + 3];
                    [p[0] as f64, p[1] as f64, p[2] as f64]
                })
                .collect();
            let triangles = triangulate_polygon(&points).map_err(|reason| {
                let tokens = face
                    .iter()
                    .map(|i| (i + 1).to_string())
                    .collect::<Vec<_>>()
                    .join(" ");
                InputError::new(
                    file,
                    at(),
                    format!("{arity} vertices: {tokens}"),
                    format!("{reason}: split the polygon into triangles or convex polygons"),
                )
            })?;
            for t in triangles {
                mesh.indices.extend(t.map(global));
            }
        }
    }
    mesh.validate(file)?;
    Ok(mesh)
}

/// Triangulates a polygon of `points` (4 or more, in order) in its own plane. Returns triangles
/// as indices into `points`, in the polygon's winding:
/// - a convex polygon gives the fan from vertex 0, `(0, k, k + 1)` (what fan triangulation, and
///   this loader before, always gave);
/// - a concave simple polygon is ear-clipped;
/// - a zero-area, non-planar (a vertex off the best plane by more than 1e-3 of the polygon's
///   size) or self-intersecting polygon is an error (the reason is returned).
pub fn triangulate_polygon(points: &[[f64; 3]]) -> Result<Vec<[usize; 3]>, String> {
    let n = points.len();
    let fan = || (1..n - 1).map(|k| [0, k, k + 1]).collect::<Vec<_>>();
    // Newell's normal: twice the vector area, robust for concave polygons.
    let mut normal = [0.0f64; 3];
    for i in 0..n {
        let (a, b) = (points[i], points[(i + 1) % n]);
        normal[0] += (a[1] - b[1]) * (a[2] + b[2]);
        normal[1] += (a[2] - b[2]) * (a[0] + b[0]);
        normal[2] += (a[0] - b[0]) * (a[1] + b[1]);
    }
    let (lo, hi) = bounding_box(points.iter().copied());
    let size = ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2) + (hi[2] - lo[2]).powi(2)).sqrt();
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let cross3 = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    // The plane: through vertex 0, the vertex farthest from it and the vertex farthest from that
    // line (robust even where the vector area vanishes, as for a symmetric bow tie).
    let a = points[0];
    let far = points
        .iter()
        .copied()
        .max_by(|p, q| dot(sub(*p, a), sub(*p, a)).total_cmp(&dot(sub(*q, a), sub(*q, a))))
        .unwrap_or(a);
    let spread = points
        .iter()
        .map(|p| cross3(sub(far, a), sub(*p, a)))
        .max_by(|p, q| dot(*p, *p).total_cmp(&dot(*q, *q)))
        .unwrap_or([0.0; 3]);
    let spread_length = dot(spread, spread).sqrt();
    if size == 0.0 || spread_length <= 1.0e-9 * size * size {
        return Err("zero-area polygon (its vertices are on one line)".into());
    }
    // Oriented with the polygon's winding (the vector area) where it has one.
    let sign = if dot(spread, normal) < 0.0 { -1.0 } else { 1.0 };
    let nrm = spread.map(|c| sign * c / spread_length);
    let centroid = [0, 1, 2].map(|k| points.iter().map(|p| p[k]).sum::<f64>() / n as f64);
    for p in points {
        let off = dot(sub(*p, centroid), nrm).abs();
        if off > 1.0e-3 * size {
            return Err(format!(
                "non-planar polygon (a vertex is {off:.3e} off its plane, size {size:.3e})"
            ));
        }
    }
    // A 2D frame (u, v) in the plane with u x v = normal: the polygon winds counter-clockwise.
    let helper = if nrm[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let u = cross3(helper, nrm);
    let ul = dot(u, u).sqrt();
    let u = u.map(|c| c / ul);
    let v = cross3(nrm, u);
    let flat: Vec<[f64; 2]> = points
        .iter()
        .map(|p| {
            let d = sub(*p, centroid);
            [dot(d, u), dot(d, v)]
        })
        .collect();
    let eps = 1.0e-12 * size * size;
    let orient = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| {
        (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    };
    // Simple: no two non-adjacent edges meet (touching counts).
    let on_segment = |a: [f64; 2], b: [f64; 2], p: [f64; 2]| {
        p[0] >= a[0].min(b[0]) - 1e-12 * size
            && p[0] <= a[0].max(b[0]) + 1e-12 * size
            && p[1] >= a[1].min(b[1]) - 1e-12 * size
            && p[1] <= a[1].max(b[1]) + 1e-12 * size
    };
    let segments_meet = |a: [f64; 2], b: [f64; 2], c: [f64; 2], d: [f64; 2]| {
        let (o1, o2) = (orient(a, b, c), orient(a, b, d));
        let (o3, o4) = (orient(c, d, a), orient(c, d, b));
        let side = |o: f64| {
            if o > eps {
                1
            } else if o < -eps {
                -1
            } else {
                0
            }
        };
        let (s1, s2, s3, s4) = (side(o1), side(o2), side(o3), side(o4));
        if s1 * s2 < 0 && s3 * s4 < 0 {
            return true;
        }
        (s1 == 0 && on_segment(a, b, c))
            || (s2 == 0 && on_segment(a, b, d))
            || (s3 == 0 && on_segment(c, d, a))
            || (s4 == 0 && on_segment(c, d, b))
    };
    for i in 0..n {
        for j in i + 1..n {
            let adjacent = j == i + 1 || (i == 0 && j == n - 1);
            if adjacent {
                continue;
            }
            if segments_meet(flat[i], flat[(i + 1) % n], flat[j], flat[(j + 1) % n]) {
                return Err(format!(
                    "self-intersecting polygon (edges {}-{} and {}-{} meet)",
                    i + 1,
                    (i + 1) % n + 1,
                    j + 1,
                    (j + 1) % n + 1
                ));
            }
        }
    }
    let area = dot(normal, nrm);
    if area <= 1.0e-9 * size * size {
        return Err("zero-area polygon".into());
    }
    let convex = (0..n).all(|i| orient(flat[i], flat[(i + 1) % n], flat[(i + 2) % n]) >= -eps);
    if convex {
        return Ok(fan());
    }
    // Ear clipping: cut off a convex corner whose triangle holds no other vertex, until three are
    // left.
    let mut left: Vec<usize> = (0..n).collect();
    let mut triangles = Vec::with_capacity(n - 2);
    while left.len() > 3 {
        let m = left.len();
        let ear = (0..m).find(|&k| {
            let (a, b, c) = (left[(k + m - 1) % m], left[k], left[(k + 1) % m]);
            if orient(flat[a], flat[b], flat[c]) <= eps {
                return false;
            }
            left.iter().all(|&q| {
                q == a
                    || q == b
                    || q == c
                    || orient(flat[a], flat[b], flat[q]) < -eps
                    || orient(flat[b], flat[c], flat[q]) < -eps
                    || orient(flat[c], flat[a], flat[q]) < -eps
            })
        });
        let Some(k) = ear else {
            return Err("polygon cannot be triangulated (no ear found)".into());
        };
        triangles.push([left[(k + m - 1) % m], left[k], left[(k + 1) % m]]);
        left.remove(k);
    }
    triangles.push([left[0], left[1], left[2]]);
    Ok(triangles)
}

/// Checks what `tobj` does not report with a line number: numbers in `v`/`vt` lines, and that every
/// face index is a non-zero integer naming an already-declared `v`/`vt`/`vn` (negative indices count
/// back). Guarantees `tobj` only ever sees in-range indices. Returns the 1-based line of every
/// face of three or more vertices, in order (`tobj` keeps faces in file order).
fn prescan_obj(text: &str, file: &str) -> Result<Vec<usize>, InputError> {
    let mut counts = [0usize; 3]; // v, vt, vn
    let mut face_lines = Vec::new();
    for (n, raw_line) in text.lines().enumerate() {
        let line = n + 1;
        let mut words = raw_line.split_whitespace();
        let Some(keyword) = words.next() else {
            continue;
        };
        let err = |what: &str, value: &str, reason: &str| {
            InputError::new(file, format!("line {line}, {what}"), value, reason)
        };
        match keyword {
            "v" | "vt" | "vn" => {
                let (k, need) = match keyword {
                    "v" => (0, 3),
                    "vt" => (1, 2),
                    _ => (2, 3),
                };
                let values: Vec<&str> = words.clone().take(need).collect();
                if values.len() < need {
                    return Err(err(
                        keyword,
                        raw_line.trim(),
                        &format!("expected {need} numbers"),
                    ));
                }
                for v in values {
                    match v.parse::<f32>() {
                        Ok(x) if x.is_finite() => {}
                        _ => return Err(err(keyword, v, "expected a finite number")),
                    }
                }
                counts[k] += 1;
            }
            "f" | "l" => {
                if keyword == "f" && words.clone().count() >= 3 {
                    face_lines.push(line);
                }
                for token in words {
                    let parts: Vec<&str> = token.split('/').collect();
                    if parts.len() > 3 {
                        return Err(err("face", token, "expected v, v/vt, v//vn or v/vt/vn"));
                    }
                    for (k, part) in parts.iter().enumerate() {
                        if part.is_empty() {
                            continue;
                        }
                        let kind = ["vertex", "texture coordinate", "normal"][k];
                        let index: isize = part.parse().map_err(|_| {
                            err("face", token, &format!("expected an integer {kind} index"))
                        })?;
                        let available = counts[k] as isize;
                        let ok = if index > 0 {
                            index <= available
                        } else {
                            index < 0 && available + index >= 0
                        };
                        if !ok {
                            return Err(err(
                                "face",
                                token,
                                &format!(
                                    "{kind} index out of range: {} declared so far (indices start at 1; negative ones count back)",
                                    counts[k]
                                ),
                            ));
                        }
                    }
                }
            }
            _ => {}
        }
    }
    Ok(face_lines)
}

#[cfg(test)]
mod tests {
    use super::super::test_util::assert_mentions;
    use super::*;

    const QUAD_OBJ: &str = "# a card\nv -1 0 0\nv 1 0 0\nv 1 0 2\nv -1 0 2\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3 4/4\n";

    fn texture() -> Rgba8Image {
        Rgba8Image::new(4, 4, [10, 20, 30, 255])
    }

    #[test]
    fn obj_quad_is_triangulated_with_flipped_v() {
        let card = |up| parse_obj_mesh("card", QUAD_OBJ.as_bytes(), "card.obj", up, texture());
        let m = card(UpAxis::Z).unwrap();
        assert_eq!(m.indices.len(), 6);
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.positions[2], [1.0, 0.0, 2.0]);
        assert_eq!(m.uvs[0], [0.0, 1.0]);
        assert_eq!(m.uvs[2], [1.0, 0.0]);
        let y = card(UpAxis::Y).unwrap();
        assert_eq!(y.positions[2], [1.0, -2.0, 0.0]);
    }

    #[test]
    fn obj_errors_name_file_line_and_value() {
        let bad = |text: &str| {
            parse_obj_mesh("t", text.as_bytes(), "tree.obj", UpAxis::Z, texture())
                .unwrap_err()
                .to_string()
        };
        let e = bad("v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nf 1/1 2/1 7/1\n");
        assert_mentions(&e, &["tree.obj", "line 5", "7/1", "out of range"]);
        let e = bad("v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nf 1/1 2/1 0/1\n");
        assert_mentions(&e, &["line 5", "0/1"]);
        let e = bad("v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nf 1/0 2/1 3/1\n");
        assert_mentions(&e, &["line 5", "1/0"]);
        let e = bad("v 0 nan 0\n");
        assert_mentions(&e, &["line 1", "nan"]);
        let e = bad("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n");
        assert!(e.contains("texture coordinate"), "{e}");
        let e = bad("# nothing\n");
        assert!(e.contains("geometry") || e.contains("triangle"), "{e}");
        let mut many = String::new();
        for i in 0..25 {
            many.push_str(&format!("v {i} 0 0\nv {i} 1 0\nv {i} 1 1\nvt 0 0\n"));
        }
        for i in 0..25 {
            let b = 3 * i + 1;
            many.push_str(&format!("f {}/1 {}/1 {}/1\n", b, b + 1, b + 2));
        }
        let e = bad(&many);
        assert_mentions(&e, &["triangle count", "25"]);
    }
}

//! Stanford PLY meshes (ASCII, binary little and big endian), parsed by `ply-rs-bw`.
//!
//! The crate parses the header and the payload and reports syntax errors with the
//! file line; this module checks what the parse cannot know (coordinates finite, face
//! indices naming a vertex, faces with at least three corners) and locates those
//! errors too: in an ASCII file at the element's own line, in a binary file by the
//! element's index (binary data has no lines).

use super::ObjMesh;
use crate::error::{Error, Result};
use crate::scene::Material;
use glam::Vec3;
use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::{DefaultElement, Encoding, Property};
use std::path::Path;

/// A PLY mesh: the triangles (faces split as fans `(0, i, i + 1)`, one default
/// material) and, when the file has `red`/`green`/`blue` vertex properties, one linear
/// colour per vertex in [0, 1] (integer channels divided by their maximum).
#[derive(Clone, Debug, Default)]
pub struct PlyMesh {
    pub mesh: ObjMesh,
    /// Empty, or one colour per vertex. Loaded and checked; the renderer does not use
    /// them yet (materials are per triangle).
    pub colors: Vec<Vec3>,
}

/// Loads a PLY file (ASCII or binary). Vertex normals (`nx ny nz`) are kept when all
/// three properties are present, texture coordinates when `u v`, `s t` or
/// `texture_u texture_v` are.
pub fn load_ply(path: &Path) -> Result<PlyMesh> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    load_ply_from_bytes(&bytes, path)
}

/// Parses PLY data already in memory; `path` names it in error messages.
pub fn load_ply_from_bytes(bytes: &[u8], path: &Path) -> Result<PlyMesh> {
    let ply = Parser::<DefaultElement>::new()
        .read_ply(&mut &bytes[..])
        .map_err(|e| {
            let text = e.to_string();
            let message = match e.line() {
                Some(l) => text
                    .strip_prefix(&format!("Line {l}: "))
                    .unwrap_or(&text)
                    .to_string(),
                None => text,
            };
            let message = message.replace("\n'", "'").replace("\n\t", "; ");
            Error::input(
                path,
                e.line().unwrap_or(0),
                0,
                format!("bad PLY: {message}"),
            )
        })?;
    let header_lines = header_line_count(bytes);
    let ascii = matches!(ply.header.encoding, Encoding::Ascii);
    // First payload line of each element in an ASCII file (elements follow in header
    // order, one per line).
    let mut first_line = std::collections::HashMap::new();
    let mut line = header_lines + 1;
    for (name, def) in &ply.header.elements {
        first_line.insert(name.as_str(), line);
        line += def.count;
    }
    let at = |element: &str, index: usize, message: String| -> Error {
        let line = if ascii {
            first_line.get(element).map_or(0, |l| l + index)
        } else {
            0
        };
        Error::input(path, line, 0, format!("{element} {index}: {message}"))
    };
    let header_error = |message: &str| Error::input(path, 0, 0, format!("bad PLY: {message}"));

    let empty = Vec::new();
    let vertices = ply.payload.get("vertex").unwrap_or(&empty);
    let has = |name: &str| {
        ply.header
            .elements
            .get("vertex")
            .is_some_and(|d| d.properties.contains_key(name))
    };
    let xyz = has("x") && has("y") && has("z");
    if !vertices.is_empty() && !xyz {
        return Err(header_error("`element vertex` lacks an x, y or z property"));
    }
    if vertices.len() > u32::MAX as usize {
        return Err(header_error("more than 2^32 vertices"));
    }
    let with_normals = has("nx") && has("ny") && has("nz");
    let with_colors = has("red") && has("green") && has("blue");
    // Texture coordinates under the names in use: `u v` (Blender, Meshlab), `s t`,
    // `texture_u texture_v` (VCGlib).
    let uv_names = [("u", "v"), ("s", "t"), ("texture_u", "texture_v")]
        .into_iter()
        .find(|(a, b)| has(a) && has(b));

    let mut out = PlyMesh::default();
    let mesh = &mut out.mesh;
    for (i, v) in vertices.iter().enumerate() {
        let get = |name: &str| -> Result<f32> {
            let value = v
                .get(name)
                .and_then(scalar)
                .ok_or_else(|| at("vertex", i, format!("`{name}` is not a number")))?;
            if !value.is_finite() {
                return Err(at("vertex", i, format!("`{name}` is {value}, not finite")));
            }
            Ok(value as f32)
        };
        let triple = |a, b, c| -> Result<Vec3> { Ok(Vec3::new(get(a)?, get(b)?, get(c)?)) };
        mesh.positions.push(triple("x", "y", "z")?);
        if with_normals {
            mesh.normals
                .push(triple("nx", "ny", "nz")?.normalize_or_zero());
        }
        if let Some((un, vn)) = uv_names {
            mesh.texcoords.push(glam::Vec2::new(get(un)?, get(vn)?));
        }
        if with_colors {
            let channel = |name: &str| -> Result<f32> {
                v.get(name)
                    .and_then(color_channel)
                    .ok_or_else(|| at("vertex", i, format!("`{name}` is not a colour")))
            };
            out.colors.push(Vec3::new(
                channel("red")?,
                channel("green")?,
                channel("blue")?,
            ));
        }
    }

    let faces = ply.payload.get("face").unwrap_or(&empty);
    let n = mesh.positions.len();
    for (j, f) in faces.iter().enumerate() {
        let list = f
            .get("vertex_indices")
            .or_else(|| f.get("vertex_index"))
            .ok_or_else(|| at("face", j, "no `vertex_indices` list".into()))?;
        let corners = index_list(list).ok_or_else(|| {
            at(
                "face",
                j,
                "`vertex_indices` is not a list of integers".into(),
            )
        })?;
        if corners.len() < 3 {
            return Err(at(
                "face",
                j,
                format!("{} corners, a face needs at least 3", corners.len()),
            ));
        }
        let mut idx = Vec::with_capacity(corners.len());
        for c in corners {
            if c < 0 || c as usize >= n {
                return Err(at(
                    "face",
                    j,
                    format!("vertex index {c} out of range (the file has {n} vertices)"),
                ));
            }
            idx.push(c as u32);
        }
        for k in 1..idx.len() - 1 {
            mesh.indices.push([idx[0], idx[k], idx[k + 1]]);
            mesh.material_ids.push(0);
        }
    }
    mesh.materials.push(Material::default());
    if mesh.indices.is_empty() {
        mesh.warnings.push(format!(
            "{}: no faces; loading an empty mesh",
            path.display()
        ));
    }
    Ok(out)
}

/// Lines up to and including `end_header` (the whole file when there is none: the
/// parser has then already failed).
fn header_line_count(bytes: &[u8]) -> usize {
    let mut lines = 0;
    for line in bytes.split(|&b| b == b'\n') {
        lines += 1;
        if line.trim_ascii() == b"end_header" {
            break;
        }
    }
    lines
}

fn scalar(p: &Property) -> Option<f64> {
    Some(match *p {
        Property::Char(v) => v as f64,
        Property::UChar(v) => v as f64,
        Property::Short(v) => v as f64,
        Property::UShort(v) => v as f64,
        Property::Int(v) => v as f64,
        Property::UInt(v) => v as f64,
        Property::Float(v) => v as f64,
        Property::Double(v) => v,
        _ => return None,
    })
}

/// A colour channel in [0, 1]: unsigned integers over their maximum, floats as they
/// are (clamped).
fn color_channel(p: &Property) -> Option<f32> {
    let v = match *p {
        Property::UChar(v) => v as f32 / 255.0,
        Property::UShort(v) => v as f32 / 65535.0,
        Property::Float(v) => v,
        Property::Double(v) => v as f32,
        _ => return None,
    };
    v.is_finite().then(|| v.clamp(0.0, 1.0))
}

fn index_list(p: &Property) -> Option<Vec<i64>> {
    Some(match p {
        Property::ListChar(v) => v.iter().map(|&x| x as i64).collect(),
        Property::ListUChar(v) => v.iter().map(|&x| x as i64).collect(),
        Property::ListShort(v) => v.iter().map(|&x| x as i64).collect(),
        Property::ListUShort(v) => v.iter().map(|&x| x as i64).collect(),
        Property::ListInt(v) => v.iter().map(|&x| x as i64).collect(),
        Property::ListUInt(v) => v.iter().map(|&x| x as i64).collect(),
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The source mesh: a quad (split as a fan) and a triangle, with normals and 8-bit
    /// colours; coordinates that are not short decimals, so a lossy path would show.
    /// Positions, normals, 8-bit colours, faces.
    type Source = (Vec<Vec3>, Vec<Vec3>, Vec<[u8; 3]>, Vec<Vec<u32>>);

    fn source() -> Source {
        let positions = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0 / 3.0, 0.0),
            Vec3::new(0.0, 1.0, -2.5e-7),
            Vec3::new(0.5, 2.0, 1e5),
        ];
        let normals = vec![
            Vec3::Z,
            Vec3::Z,
            Vec3::Y,
            Vec3::NEG_X,
            Vec3::new(0.6, 0.0, 0.8),
        ];
        let colors = vec![
            [255, 0, 0],
            [0, 255, 0],
            [0, 0, 255],
            [51, 102, 153],
            [0, 0, 0],
        ];
        let faces = vec![vec![0, 1, 2, 3], vec![3, 2, 4]];
        (positions, normals, colors, faces)
    }

    const HEADER_PROPS: &str = "element vertex 5\nproperty float x\nproperty float y\n\
        property float z\nproperty float nx\nproperty float ny\nproperty float nz\n\
        property uchar red\nproperty uchar green\nproperty uchar blue\n\
        element face 2\nproperty list uchar int vertex_indices\nend_header\n";

    fn ascii_ply() -> Vec<u8> {
        let (p, n, c, f) = source();
        let mut s = format!("ply\nformat ascii 1.0\ncomment round trip\n{HEADER_PROPS}");
        for i in 0..p.len() {
            // `{:?}` prints the shortest decimal that parses back to the same f32.
            s += &format!(
                "{:?} {:?} {:?} {:?} {:?} {:?} {} {} {}\n",
                p[i].x, p[i].y, p[i].z, n[i].x, n[i].y, n[i].z, c[i][0], c[i][1], c[i][2]
            );
        }
        for face in &f {
            let idx: Vec<String> = face.iter().map(u32::to_string).collect();
            s += &format!("{} {}\n", face.len(), idx.join(" "));
        }
        s.into_bytes()
    }

    fn binary_ply() -> Vec<u8> {
        binary_ply_with(false)
    }

    fn binary_ply_with(big_endian: bool) -> Vec<u8> {
        let (p, n, c, f) = source();
        let order = if big_endian { "big" } else { "little" };
        let mut b = format!("ply\nformat binary_{order}_endian 1.0\n{HEADER_PROPS}").into_bytes();
        let f32_bytes = |v: f32| {
            if big_endian {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            }
        };
        let i32_bytes = |v: i32| {
            if big_endian {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            }
        };
        for i in 0..p.len() {
            for v in p[i].to_array().into_iter().chain(n[i].to_array()) {
                b.extend(f32_bytes(v));
            }
            b.extend(c[i]);
        }
        for face in &f {
            b.push(face.len() as u8);
            for &i in face {
                b.extend(i32_bytes(i as i32));
            }
        }
        b
    }

    fn check_round_trip(bytes: &[u8], name: &str) {
        let (p, n, c, _) = source();
        let got = load_ply_from_bytes(bytes, Path::new(name)).unwrap();
        // Positions bit-exact: both encodings carry the f32 values exactly.
        assert_eq!(got.mesh.positions.len(), p.len());
        for (a, b) in got.mesh.positions.iter().zip(&p) {
            assert_eq!(
                a.to_array().map(f32::to_bits),
                b.to_array().map(f32::to_bits)
            );
        }
        // The source normals are unit length, so normalising keeps them (to 1 ulp).
        for (a, b) in got.mesh.normals.iter().zip(&n) {
            assert!((*a - *b).abs().max_element() <= f32::EPSILON, "{a} vs {b}");
        }
        assert_eq!(got.mesh.normals.len(), n.len());
        // The quad as the fan (0,1,2), (0,2,3); the triangle as it is.
        assert_eq!(got.mesh.indices, vec![[0, 1, 2], [0, 2, 3], [3, 2, 4]]);
        assert_eq!(got.mesh.material_ids, vec![0, 0, 0]);
        assert_eq!(got.mesh.materials.len(), 1);
        let want: Vec<Vec3> = c
            .iter()
            .map(|c| Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32) / 255.0)
            .collect();
        assert_eq!(got.colors, want);
        assert!(got.mesh.warnings.is_empty(), "{:?}", got.mesh.warnings);
    }

    #[test]
    fn ascii_round_trip() {
        check_round_trip(&ascii_ply(), "mesh.ply");
    }

    #[test]
    fn binary_little_endian_round_trip() {
        let bytes = binary_ply();
        check_round_trip(&bytes, "mesh.ply");
        // The two files hold the same mesh through different encodings.
        assert_ne!(bytes, ascii_ply());
    }

    #[test]
    fn binary_big_endian_round_trip() {
        let bytes = binary_ply_with(true);
        check_round_trip(&bytes, "mesh.ply");
        assert_ne!(bytes, binary_ply());
    }

    #[test]
    fn positions_only_has_no_normals_or_colours() {
        let text = "ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\n\
            property double y\nproperty double z\nelement face 1\n\
            property list uchar uint vertex_index\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
        let got = load_ply_from_bytes(text.as_bytes(), Path::new("t.ply")).unwrap();
        assert_eq!(got.mesh.positions[2], Vec3::Y);
        assert!(got.mesh.normals.is_empty() && got.colors.is_empty());
        assert_eq!(got.mesh.indices, vec![[0, 1, 2]]);
    }

    fn error_of(bytes: &[u8]) -> String {
        load_ply_from_bytes(bytes, Path::new("bad.ply"))
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn malformed_files_give_located_errors() {
        let good = String::from_utf8(ascii_ply()).unwrap();
        // The header has 16 lines; vertex 0 is line 17, face 0 line 22, face 1 line 23.
        let bad_index = good.replace("3 3 2 4\n", "3 3 2 5\n");
        let msg = error_of(bad_index.as_bytes());
        assert!(msg.starts_with("bad.ply:23: face 1:"), "{msg}");
        assert!(msg.contains("vertex index 5 out of range"), "{msg}");

        let two_corners = good.replace("3 3 2 4\n", "2 3 2\n");
        let msg = error_of(two_corners.as_bytes());
        assert!(msg.starts_with("bad.ply:23: face 1:"), "{msg}");
        assert!(msg.contains("2 corners"), "{msg}");

        // The crate's ASCII grammar refuses NaN itself (binary NaN: the next test).
        let nan = good.replacen("1.0 0.0 0.0", "1.0 NaN 0.0", 1);
        assert_ne!(nan, good);
        let msg = error_of(nan.as_bytes());
        assert!(msg.starts_with("bad.ply:18: bad PLY:"), "{msg}");

        // A syntax error in the header, located by the parser.
        let header = good.replace("property float nx", "property flaot nx");
        let msg = error_of(header.as_bytes());
        assert!(msg.starts_with("bad.ply:8"), "{msg}");

        // A non-number in the payload.
        let word = good.replacen("1.0 0.0 0.0", "1.0 zero 0.0", 1);
        let msg = error_of(word.as_bytes());
        assert!(msg.starts_with("bad.ply:18"), "{msg}");
    }

    #[test]
    fn binary_errors_name_the_element_and_truncation_is_an_error() {
        let mut bytes = binary_ply();
        // The last face's last index (4) becomes 9.
        let n = bytes.len();
        bytes[n - 4..].copy_from_slice(&9i32.to_le_bytes());
        let msg = error_of(&bytes);
        assert!(msg.starts_with("bad.ply: face 1:"), "{msg}");
        assert!(msg.contains("vertex index 9"), "{msg}");

        // Vertex 1's y becomes NaN: 24 + 3 bytes per vertex after the header.
        let mut bytes = binary_ply();
        let header = bytes
            .windows(11)
            .position(|w| w == b"end_header\n")
            .unwrap()
            + 11;
        let y1 = header + 27 + 4;
        bytes[y1..y1 + 4].copy_from_slice(&f32::NAN.to_le_bytes());
        let msg = error_of(&bytes);
        assert!(msg.starts_with("bad.ply: vertex 1: `y` is NaN"), "{msg}");

        let whole = binary_ply();
        for cut in [whole.len() - 1, whole.len() - 30, 40, 3] {
            let r = load_ply_from_bytes(&whole[..cut], Path::new("bad.ply"));
            assert!(r.is_err(), "a file cut at byte {cut} loaded");
        }
        assert!(error_of(b"not a ply file\n").starts_with("bad.ply"));
    }
}

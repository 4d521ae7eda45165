//! Wavefront OBJ/MTL meshes, parsed by `tobj`.
//!
//! tobj reports no line numbers, and on some malformed input it either silently
//! accepts garbage (`v nan 0 0`), or panics (an index of 0 overflows, `Kd 0.5` has
//! fewer than three components). So every file is first read into memory and
//! pre-scanned here: `v`/`vn` coordinates must be finite numbers and `f` indices must
//! name an element defined above them, with the error located at the OBJ line. Only
//! input that passed the scan is handed to tobj, from the same buffer.

use super::mtl_maps::{MtlMap, MtlMapKind, attach_maps};
use crate::error::{Error, Result};
use crate::scene::Material;
use crate::texture::TextureCache;
use glam::{Vec2, Vec3};
use std::cell::RefCell;
use std::io::Cursor;
use std::path::Path;

/// A triangle mesh read from an OBJ file, all its objects and groups merged.
#[derive(Clone, Debug, Default)]
pub struct ObjMesh {
    pub positions: Vec<Vec3>,
    /// Per-vertex normals from `vn` records: empty, or one per position (zero where a
    /// part of the file had none, meaning "use the geometric normal").
    pub normals: Vec<Vec3>,
    /// Per-vertex texture coordinates from `vt` records: empty, or one per position
    /// ((0, 0) where a part of the file had none).
    pub texcoords: Vec<glam::Vec2>,
    pub indices: Vec<[u32; 3]>,
    /// Per triangle, an index into `materials`.
    pub material_ids: Vec<u32>,
    /// Materials from the MTL libraries, plus a default one for faces without `usemtl`.
    pub materials: Vec<Material>,
    /// Problems that did not stop the load (a missing MTL file, an unknown `usemtl`).
    pub warnings: Vec<String>,
}

impl ObjMesh {
    pub fn triangle_count(&self) -> usize {
        self.indices.len()
    }
}

/// Loads an OBJ file and the MTL libraries it names. Polygons are split as fans
/// `(0, i, i + 1)`; points and lines are ignored.
pub fn load_obj(path: &Path) -> Result<ObjMesh> {
    load_obj_with(path, &mut TextureCache::new())
}

/// [`load_obj`] sharing a texture cache with the other meshes of a scene: the
/// textures the MTL files name (`map_Kd`, `map_Ks`, `map_d`) are decoded once per file.
pub fn load_obj_with(path: &Path, textures: &mut TextureCache) -> Result<ObjMesh> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    load_obj_from_bytes_with(&bytes, path, textures)
}

/// Parses OBJ data already in memory, as [`load_obj`] does after reading the file:
/// `path` names it in error messages, and MTL libraries are looked up beside it. The
/// entry point of the `obj` fuzz target.
pub fn load_obj_from_bytes(bytes: &[u8], path: &Path) -> Result<ObjMesh> {
    load_obj_from_bytes_with(bytes, path, &mut TextureCache::new())
}

/// [`load_obj_from_bytes`] with a shared texture cache ([`load_obj_with`]).
pub fn load_obj_from_bytes_with(
    bytes: &[u8],
    path: &Path,
    textures: &mut TextureCache,
) -> Result<ObjMesh> {
    let text = utf8_or_located_error(path, bytes)?;
    prescan_obj(path, text)?;

    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let warnings = RefCell::new(Vec::new());
    let mtl_error: RefCell<Option<Error>> = RefCell::new(None);
    let maps: RefCell<Vec<MtlMap>> = RefCell::new(Vec::new());
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let loaded = tobj::load_obj_buf(&mut Cursor::new(text.as_bytes()), &options, |mtl_name| {
        let mtl_path = dir.join(mtl_name);
        match load_mtl_checked(&mtl_path) {
            Ok((r, m)) => {
                maps.borrow_mut().extend(m);
                r
            }
            Err(MtlProblem::Missing(msg)) => {
                warnings.borrow_mut().push(msg);
                Err(tobj::LoadError::OpenFileFailed)
            }
            Err(MtlProblem::Malformed(e)) => {
                mtl_error.borrow_mut().get_or_insert(e);
                Err(tobj::LoadError::MaterialParseError)
            }
        }
    });
    if let Some(e) = mtl_error.into_inner() {
        return Err(e);
    }
    let mut warnings = warnings.into_inner();
    let (models, materials) = loaded.map_err(|e| {
        // The pre-scan catches what it can with a line; this is what is left.
        Error::input(path, 0, 0, format!("cannot parse OBJ: {e}"))
    })?;
    // A missing library already produced a warning; tobj returns its error here only
    // when no library loaded at all.
    let tobj_materials = materials.unwrap_or_default();

    let mut mesh = ObjMesh {
        materials: tobj_materials.iter().map(material_from_mtl).collect(),
        ..Default::default()
    };
    attach_maps(
        &mut mesh.materials,
        &maps.into_inner(),
        textures,
        &mut warnings,
    )?;
    let mut default_id = None;
    let any_normals = models
        .iter()
        .any(|m| !m.mesh.normals.is_empty() && m.mesh.normals.len() == m.mesh.positions.len());
    let has_uvs = |m: &tobj::Mesh| m.texcoords.len() / 2 == m.positions.len() / 3;
    let any_uvs = models
        .iter()
        .any(|m| !m.mesh.texcoords.is_empty() && has_uvs(&m.mesh));
    for model in &models {
        let m = &model.mesh;
        let base = mesh.positions.len();
        if base + m.positions.len() / 3 > u32::MAX as usize {
            return Err(Error::input(path, 0, 0, "more than 2^32 vertices"));
        }
        mesh.positions.extend(
            m.positions
                .chunks_exact(3)
                .map(|p| Vec3::new(p[0], p[1], p[2])),
        );
        if any_normals {
            if m.normals.len() == m.positions.len() {
                mesh.normals.extend(
                    m.normals
                        .chunks_exact(3)
                        .map(|n| Vec3::new(n[0], n[1], n[2])),
                );
            } else {
                mesh.normals.resize(mesh.positions.len(), Vec3::ZERO);
            }
        }
        if any_uvs {
            if has_uvs(m) {
                mesh.texcoords
                    .extend(m.texcoords.chunks_exact(2).map(|t| Vec2::new(t[0], t[1])));
            } else {
                mesh.texcoords.resize(mesh.positions.len(), Vec2::ZERO);
            }
        }
        let material = match m.material_id {
            Some(id) if id < mesh.materials.len() => id as u32,
            _ => *default_id.get_or_insert_with(|| {
                mesh.materials.push(Material::default());
                (mesh.materials.len() - 1) as u32
            }),
        };
        let base = base as u32;
        for t in m.indices.chunks_exact(3) {
            mesh.indices.push([base + t[0], base + t[1], base + t[2]]);
            mesh.material_ids.push(material);
        }
    }
    if mesh.materials.is_empty() {
        mesh.materials.push(Material::default());
    }
    if mesh.indices.is_empty() {
        // Not an error (issue 13): an empty scene is a valid scene, as it is from
        // `SceneBuilder`; the render warns that only the background shows.
        warnings.push(format!(
            "{}: no triangles (no `f` records); loading an empty mesh",
            path.display()
        ));
    }
    if !tobj_materials.is_empty() && default_id.is_some() {
        warnings.push(format!(
            "{}: some faces have no (or an unknown) `usemtl`; they get the default material",
            path.display()
        ));
    }
    mesh.warnings = warnings;
    Ok(mesh)
}

/// Maps an MTL material to ours, following the `illum` models of the MTL spec:
/// 0/1 diffuse, 2 + Blinn-Phong highlight, 3 mirror (weight Ks, or 1 if Ks is zero),
/// 5 mirror with Fresnel (treated as a mirror), 4/6/7 glass (refraction with Fresnel;
/// transmission = Tf, or 1 - d, or 1; ior = Ni, default 1.5).
pub fn material_from_mtl(m: &tobj::Material) -> Material {
    let v3 = |c: Option<[f32; 3]>| c.map(Vec3::from_array);
    let kd = v3(m.diffuse).unwrap_or(Vec3::splat(0.8));
    let ks = v3(m.specular).unwrap_or(Vec3::ZERO);
    let ior = m.optical_density.filter(|n| *n > 0.0).unwrap_or(1.5);
    let dissolve = match (
        m.dissolve,
        m.unknown_param.get("Tr").and_then(|s| parse_f32(s)),
    ) {
        (Some(d), _) => d,
        (None, Some(tr)) => 1.0 - tr,
        (None, None) => 1.0,
    }
    .clamp(0.0, 1.0);
    let tf = m
        .unknown_param
        .get("Tf")
        .and_then(|s| parse_vec3_lenient(s));
    let illum = m
        .illumination_model
        .unwrap_or(if ks == Vec3::ZERO { 1 } else { 2 });

    let mut out = Material {
        name: m.name.clone(),
        diffuse: kd,
        shininess: m
            .shininess
            .filter(|s| s.is_finite() && *s >= 0.0)
            .unwrap_or(32.0),
        ior,
        emission: v3(m.emissive).unwrap_or(Vec3::ZERO),
        ..Material::default()
    };
    match illum {
        0 | 1 => {}
        2 => out.specular = ks,
        3 | 5 => {
            out.specular = ks;
            out.mirror = if ks == Vec3::ZERO { Vec3::ONE } else { ks };
        }
        4 | 6 | 7 => {
            out.specular = ks;
            out.transmission = tf.unwrap_or(Vec3::splat(if dissolve < 1.0 {
                1.0 - dissolve
            } else {
                1.0
            }));
            // Energy the glass transmits is not also scattered diffusely.
            out.diffuse = kd * (1.0 - out.transmission.max_element()).max(0.0);
        }
        _ => out.specular = ks,
    }
    // A plain dissolve (`d < 1` or `Tr > 0`) on a non-glass model still means "see-through".
    if out.transmission == Vec3::ZERO && dissolve < 1.0 {
        out.transmission = tf.unwrap_or(Vec3::splat(1.0 - dissolve));
        out.diffuse *= dissolve;
    }
    out
}

fn parse_f32(s: &str) -> Option<f32> {
    s.split_whitespace().next()?.parse().ok()
}

/// `r [g b]`: one value means grey, as the MTL spec allows.
fn parse_vec3_lenient(s: &str) -> Option<Vec3> {
    let v: Vec<f32> = s
        .split_whitespace()
        .map(str::parse)
        .collect::<std::result::Result<_, _>>()
        .ok()?;
    match v[..] {
        [g] => Some(Vec3::splat(g)),
        [r, g, b] => Some(Vec3::new(r, g, b)),
        _ => None,
    }
}

enum MtlProblem {
    Missing(String),
    Malformed(Error),
}

/// Reads an MTL file, checks the records we use (colours: 1 or 3 finite numbers;
/// scalars: one finite number; `illum` 0..=10), expands grey colours `Kd g` to `Kd g g g`
/// (tobj panics on fewer than three) and hands the text to tobj.
/// The texture map records (`map_Kd`, `map_Ks`, `map_d`, bump maps) are collected
/// with their lines for [`attach_maps`], which tobj cannot locate.
fn load_mtl_checked(
    path: &Path,
) -> std::result::Result<(tobj::MTLLoadResult, Vec<MtlMap>), MtlProblem> {
    let bytes = std::fs::read(path).map_err(|e| {
        MtlProblem::Missing(format!(
            "{}: {e}; using the default material",
            path.display()
        ))
    })?;
    let text = utf8_or_located_error(path, &bytes).map_err(MtlProblem::Malformed)?;
    let mut fixed = String::with_capacity(text.len() + 64);
    let mut maps = Vec::new();
    let mut current: Option<String> = None;
    for (i, line) in text.lines().enumerate() {
        let bad =
            |col: usize, msg: String| MtlProblem::Malformed(Error::input(path, i + 1, col, msg));
        let trimmed = line.trim_start();
        let col = line.len() - trimmed.len() + 1;
        let mut words = trimmed.split_whitespace();
        let key = words.next().unwrap_or("");
        let args: Vec<&str> = words.collect();
        match key {
            "Ka" | "Kd" | "Ks" | "Ke" | "Tf" => {
                if args.first() == Some(&"spectral") || args.first() == Some(&"xyz") {
                    return Err(bad(
                        col,
                        format!(
                            "`{key} {}` is not supported: expected `{key} r g b`",
                            args[0]
                        ),
                    ));
                }
                let nums = parse_all(&args)
                    .filter(|v| (v.len() == 1 || v.len() == 3) && v.iter().all(|x| x.is_finite()));
                match nums {
                    Some(v) if v.len() == 1 => {
                        fixed.push_str(&format!("{key} {0} {0} {0}\n", v[0]));
                        continue;
                    }
                    Some(_) => {}
                    None => {
                        return Err(bad(
                            col,
                            format!(
                                "expected `{key} r g b` with 1 or 3 finite numbers, got `{trimmed}`"
                            ),
                        ));
                    }
                }
            }
            "Ns" | "Ni" | "d" | "Tr" => {
                let ok = parse_all(&args).is_some_and(|v| v.len() == 1 && v[0].is_finite());
                // `d -halo 0.5` is valid MTL; accept it by dropping the option.
                if args.first() == Some(&"-halo") && args.len() == 2 {
                    fixed.push_str(&format!("{key} {}\n", args[1]));
                    continue;
                }
                if !ok {
                    return Err(bad(
                        col,
                        format!("expected `{key}` followed by one finite number, got `{trimmed}`"),
                    ));
                }
            }
            "illum" if !(args.len() == 1 && args[0].parse::<u8>().is_ok_and(|n| n <= 10)) => {
                return Err(bad(
                    col,
                    format!("expected `illum` followed by a model number 0..10, got `{trimmed}`"),
                ));
            }
            "newmtl" if args.is_empty() => {
                return Err(bad(col, "expected a material name after `newmtl`".into()));
            }
            "newmtl" => current = Some(args.join(" ")),
            _ => {
                if let Some(kind) = MtlMapKind::from_key(key) {
                    let rest = trimmed[key.len()..].trim();
                    let map = MtlMap::parse(path, i + 1, col, key, kind, current.clone(), rest)
                        .map_err(MtlProblem::Malformed)?;
                    maps.push(map);
                }
            }
        }
        fixed.push_str(line);
        fixed.push('\n');
    }
    Ok((tobj::load_mtl_buf(&mut Cursor::new(fixed.as_bytes())), maps))
}

fn parse_all(args: &[&str]) -> Option<Vec<f32>> {
    args.iter().map(|s| s.parse::<f32>().ok()).collect()
}

/// The file as UTF-8 text, or an error at the line holding the first invalid byte
/// (which is how binary garbage shows up).
pub(super) fn utf8_or_located_error<'a>(path: &Path, bytes: &'a [u8]) -> Result<&'a str> {
    std::str::from_utf8(bytes).map_err(|e| {
        let good = &bytes[..e.valid_up_to()];
        let line = good.iter().filter(|&&b| b == b'\n').count() + 1;
        let col = good.len() - good.iter().rposition(|&b| b == b'\n').map_or(0, |p| p + 1) + 1;
        Error::input(
            path,
            line,
            col,
            "not a text file: invalid UTF-8 (binary data?)",
        )
    })
}

/// Checks what tobj trusts blindly, with OBJ line numbers: `v` needs 3 finite numbers
/// (and a non-zero `w` if a 4th is given), `vn` 3 finite numbers, `vt` 1-3 numbers, and
/// every `f` needs at least 3 corners whose `v/vt/vn` indices (1-based, or negative =
/// relative to the end) refer to elements defined above. `l` and `p` records are
/// checked too (tobj reads them with the same index code) and then ignored.
fn prescan_obj(path: &Path, text: &str) -> Result<()> {
    let (mut nv, mut nvt, mut nvn) = (0usize, 0usize, 0usize);
    for (i, line) in text.split('\n').enumerate() {
        let lineno = i + 1;
        let bytes = line.as_bytes();
        // Fast path: most lines start with "v " or "f "; skip everything else cheaply.
        let first = match bytes.iter().position(|b| !b.is_ascii_whitespace()) {
            Some(p) => p,
            None => continue,
        };
        let rest = &line[first..];
        let mut words = rest.split_ascii_whitespace();
        let key = words.next().unwrap_or("");
        let err = |msg: String| Error::input(path, lineno, first + 1, msg);
        match key {
            "v" | "vn" => {
                let mut xyz = [0f32; 3];
                for c in &mut xyz {
                    *c = match words.next().map(str::parse::<f32>) {
                        Some(Ok(x)) if x.is_finite() => x,
                        Some(Ok(x)) => {
                            return Err(err(format!("`{key}` coordinate {x} is not finite")));
                        }
                        _ => {
                            return Err(err(format!(
                                "expected `{key} x y z` with three numbers, got `{}`",
                                rest.trim_end()
                            )));
                        }
                    };
                }
                if key == "v" {
                    let extra: Vec<&str> = words.collect();
                    if extra.len() == 1 {
                        match extra[0].parse::<f32>() {
                            Ok(w)
                                if w.is_finite()
                                    && w != 0.0
                                    && (Vec3::from_array(xyz) / w).is_finite() => {}
                            _ => {
                                return Err(err(format!(
                                    "`v x y z w` needs a finite, non-zero w, got `{}`",
                                    extra[0]
                                )));
                            }
                        }
                    } else if !(extra.is_empty() || extra.len() == 3) {
                        return Err(err(format!(
                            "expected `v x y z [w]` or `v x y z r g b`, got `{}`",
                            rest.trim_end()
                        )));
                    }
                    nv += 1;
                } else {
                    nvn += 1;
                }
            }
            "vt" => {
                let n = words.clone().count();
                if !(1..=3).contains(&n) || words.any(|w| w.parse::<f32>().is_err()) {
                    return Err(err(format!(
                        "expected `vt u [v [w]]`, got `{}`",
                        rest.trim_end()
                    )));
                }
                nvt += 1;
            }
            "f" | "l" | "p" => {
                let mut corners = 0usize;
                for corner in words {
                    corners += 1;
                    let mut parts = corner.split('/');
                    for (slot, (count, what)) in
                        [(nv, "vertex"), (nvt, "texture coordinate"), (nvn, "normal")]
                            .into_iter()
                            .enumerate()
                    {
                        let Some(part) = parts.next() else { break };
                        if part.is_empty() && slot > 0 {
                            continue;
                        }
                        check_index(part, count, what).map_err(&err)?;
                    }
                    if parts.next().is_some() {
                        return Err(err(format!(
                            "face corner `{corner}` has more than three `/`-separated indices"
                        )));
                    }
                }
                let min = match key {
                    "f" => 3,
                    "l" => 2,
                    _ => 1,
                };
                if corners < min {
                    return Err(err(format!(
                        "`{key}` needs at least {min} corners, got {corners}"
                    )));
                }
            }
            _ => {}
        }
    }
    Ok(())
}

/// One OBJ index: 1..=count, or -count..=-1 counting back from the last element.
fn check_index(s: &str, count: usize, what: &str) -> std::result::Result<(), String> {
    let i: i64 = s
        .parse()
        .map_err(|_| format!("expected an integer {what} index, got `{s}`"))?;
    let ok = if i > 0 {
        (i as u64) <= count as u64
    } else {
        i < 0 && i.unsigned_abs() <= count as u64
    };
    if ok {
        Ok(())
    } else if i == 0 {
        Err(format!("{what} index 0 is invalid: OBJ indices start at 1"))
    } else {
        Err(format!(
            "{what} index {i} is out of range: {count} {what}s are defined above this line"
        ))
    }
}

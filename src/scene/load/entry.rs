//! The loaders' entry points: a scene file or a mesh chosen by extension, a mesh framed
//! as a scene, and the line and column an error points at.

use super::ObjMesh;
use super::obj::load_obj_with;
use super::ply::load_ply;
use super::toml_scene::load_toml_scene;
use crate::error::{Error, Result};
use crate::scene::{Camera, Light, Scene, SceneBuilder};
use crate::texture::TextureCache;
use glam::{Mat4, Vec3};
use std::path::Path;

/// Loads a scene, choosing the format by extension: `.toml` is a scene file, `.obj` or
/// `.ply` a mesh that gets an automatic camera and light ([`load_obj_scene`]).
pub fn load_scene(path: &Path) -> Result<Scene> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("toml") => load_toml_scene(path),
        Some("obj" | "ply") => load_obj_scene(path),
        _ => Err(Error::input(
            path,
            0,
            0,
            "unknown scene format: expected a `.toml` scene file or an `.obj` or `.ply` mesh",
        )),
    }
}

/// Loads a mesh file by extension: `.ply` through [`load_ply`] (its vertex colours are
/// dropped), anything else as OBJ through [`load_obj`](super::load_obj).
pub fn load_mesh(path: &Path) -> Result<ObjMesh> {
    load_mesh_with(path, &mut TextureCache::new())
}

/// [`load_mesh`] sharing a texture cache with the rest of a scene.
pub fn load_mesh_with(path: &Path, textures: &mut TextureCache) -> Result<ObjMesh> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("ply") => load_ply(path).map(|p| p.mesh),
        _ => load_obj_with(path, textures),
    }
}

/// A mesh (OBJ or PLY, by extension) as a complete scene: materials from its MTL, the camera of BENCHMARK.md
/// ([`Camera::framing`]), one point light at `c + d (0.8, 1.2, 0.6)` (the benchmark's
/// shadow-ray light) bright enough for an irradiance of about 1 at the centre, a weak
/// ambient term and a grey background.
pub fn load_obj_scene(path: &Path) -> Result<Scene> {
    let mesh = load_mesh(path)?;
    print_warnings(&mesh.warnings);
    let mut b = SceneBuilder::new();
    add_obj_mesh(&mut b, &mesh, Mat4::IDENTITY, None);
    // an empty mesh (issue 13) is framed as the unit cube around the origin
    let bounds = Some(b.bounds())
        .filter(|b| !b.is_empty())
        .unwrap_or(crate::geometry::Aabb::new(-Vec3::ONE, Vec3::ONE));
    let c = bounds.center();
    let d = bounds.diagonal().max(f32::MIN_POSITIVE);
    let offset = d * Vec3::new(0.8, 1.2, 0.6);
    // Irradiance at distance r from intensity I is I / r²; r = |offset|.
    b.add_light(Light::Point {
        position: c + offset,
        intensity: Vec3::splat(offset.length_squared()),
    });
    b.ambient = Vec3::splat(0.05);
    b.background = Vec3::splat(0.3);
    b.camera = Some(Camera::framing(&bounds));
    b.finish()
}

/// Appends an OBJ mesh transformed by `transform`: its materials are added to the
/// builder unless `material` overrides them all. A mirroring transform (negative
/// determinant) swaps the winding so triangles keep facing outwards.
pub fn add_obj_mesh(
    b: &mut SceneBuilder,
    mesh: &ObjMesh,
    transform: Mat4,
    material: Option<u32>,
) -> usize {
    let first_triangle = b.mesh.len();
    let positions: Vec<Vec3> = mesh
        .positions
        .iter()
        .map(|p| transform.transform_point3(*p))
        .collect();
    let normal_matrix = transform.inverse().transpose();
    let normals: Vec<Vec3> = mesh
        .normals
        .iter()
        .map(|n| normal_matrix.transform_vector3(*n).normalize_or_zero())
        .collect();
    let flip = transform.determinant() < 0.0;
    let indices: Vec<[u32; 3]> = if flip {
        mesh.indices.iter().map(|t| [t[0], t[2], t[1]]).collect()
    } else {
        mesh.indices.clone()
    };
    b.add_mesh_with_uvs(
        &positions,
        &normals,
        &mesh.texcoords,
        &indices,
        material.unwrap_or(0),
    );
    if material.is_none() {
        let ids: Vec<u32> = mesh
            .materials
            .iter()
            .map(|m| b.add_material(m.clone()))
            .collect();
        for (slot, id) in b.mesh.material[first_triangle..]
            .iter_mut()
            .zip(&mesh.material_ids)
        {
            *slot = ids[*id as usize];
        }
    }
    mesh.indices.len()
}

pub(crate) fn print_warnings(warnings: &[String]) {
    for w in warnings {
        eprintln!("warning: {w}");
    }
}

/// 1-based line and column (in characters) of byte `offset` in `text`.
pub(crate) fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let mut offset = offset;
    while !text.is_char_boundary(offset) {
        offset -= 1;
    }
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |p| p + 1);
    (line, before[line_start..].chars().count() + 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_column_counts_from_one() {
        let t = "ab\ncdé\nf";
        assert_eq!(line_column(t, 0), (1, 1));
        assert_eq!(line_column(t, 3), (2, 1));
        assert_eq!(line_column(t, 7), (2, 4));
        assert_eq!(line_column(t, 8), (3, 1));
        assert_eq!(line_column(t, 100), (3, 2));
    }
}

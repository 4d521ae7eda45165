//! Checks on a finished scene that are not errors but deserve a warning (issue 13).

use super::Scene;

/// A warning when nothing in `scene` can be hit, so the image can only show the
/// background: no primitives at all, or only degenerate (zero-area) triangles. Infinite
/// planes and instances count as visible (an instance of an object whose triangles are
/// all degenerate is not looked into).
/// `name` names the scene in the message.
pub fn nothing_visible_warning(scene: &Scene, name: &str) -> Option<String> {
    let others = scene.spheres.len()
        + scene.motion.mesh.len()
        + scene.motion.spheres.len()
        + scene.planes.len()
        + scene.instances.instances.len();
    if others > 0 {
        return None;
    }
    let triangles = scene.mesh.len();
    if triangles == 0 {
        return Some(format!(
            "{name}: the scene has no primitives; the image shows only the background"
        ));
    }
    let degenerate = (0..triangles)
        .filter(|&t| scene.mesh.geometric_normal(t) == glam::Vec3::ZERO)
        .count();
    (degenerate == triangles).then(|| {
        format!(
            "{name}: all {triangles} triangles are degenerate (zero area) and nothing else \
             is in the scene; the image shows only the background"
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Material, SceneBuilder};
    use glam::Vec3;

    #[test]
    fn empty_and_degenerate_scenes_are_reported() {
        let b = SceneBuilder::new();
        let w = nothing_visible_warning(&b.finish().unwrap(), "s").unwrap();
        assert!(w.contains("no primitives"), "{w}");

        let mut b = SceneBuilder::new();
        let m = b.add_material(Material::default());
        let p = [Vec3::ZERO, Vec3::X, Vec3::X * 2.0];
        b.add_mesh(&p, &[], &[[0, 1, 2]], m);
        let w = nothing_visible_warning(&b.finish().unwrap(), "s").unwrap();
        assert!(w.contains("all 1 triangles are degenerate"), "{w}");

        let mut b = SceneBuilder::new();
        let m = b.add_material(Material::default());
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y];
        b.add_mesh(&p, &[], &[[0, 1, 2]], m);
        assert_eq!(nothing_visible_warning(&b.finish().unwrap(), "s"), None);
    }

    #[test]
    fn a_scene_of_an_infinite_plane_or_of_instances_is_not_reported_empty() {
        // Before instances and planes counted, both warned "no primitives"
        // (scenes/instances.toml draws its mesh only through instances).
        let dir = std::env::temp_dir().join(format!("pr-checks-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let obj = dir.join("tri.obj");
        std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
        let path = dir.join("scene.toml");
        let plane = "[[plane]]\npoint = [0, 0, 0]\nnormal = [0, 1, 0]\n";
        let instanced = "[[mesh]]\nname = \"t\"\nfile = \"tri.obj\"\ninstance_only = true\n\
                         [[instance]]\nobject = \"t\"\ntranslate = [0, 0, -3]\n";
        for text in [plane, instanced] {
            let scene = crate::scene::load::parse_toml_scene(text, &path).unwrap();
            assert_eq!(nothing_visible_warning(&scene, "s"), None, "{text}");
        }
        // The same object without its instance leaves nothing to see.
        let alone = "[[mesh]]\nname = \"t\"\nfile = \"tri.obj\"\ninstance_only = true\n";
        let scene = crate::scene::load::parse_toml_scene(alone, &path).unwrap();
        assert!(nothing_visible_warning(&scene, "s").is_some());
        std::fs::remove_dir_all(&dir).ok();
    }
}

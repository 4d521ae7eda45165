//! Checks on a finished scene that are not errors but deserve a warning (issue 13).

use super::Scene;

/// A warning when nothing in `scene` can be hit, so the image can only show the
/// background: no primitives at all, or only degenerate (zero-area) triangles.
/// `name` names the scene in the message.
pub fn nothing_visible_warning(scene: &Scene, name: &str) -> Option<String> {
    let others = scene.spheres.len() + scene.motion.mesh.len() + scene.motion.spheres.len();
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
}

//! Arbitrary output variables for compositing: per pixel, the distance to the first
//! surface, its shading normal and its albedo, from one pinhole ray through the pixel
//! centre (no lens, shutter open at time 0, no filter): the auxiliary images a
//! denoiser or compositor expects, written as extra EXR channels.

use super::PixelBounds;
use super::interaction::SurfaceInteraction;
use crate::accel::SceneAccel;
use crate::film::exr::ExtraChannel;
use crate::scene::Scene;
use glam::Vec3;

/// The three AOVs of a region, row-major, row 0 at the top of the region.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Aovs {
    /// Distance from the eye along the (unit) ray to the first hit; `+inf` on a miss.
    pub depth: Vec<f32>,
    /// Unit shading normal facing the camera; zero on a miss.
    pub normal: Vec<Vec3>,
    /// The material's diffuse albedo at the hit (checker patterns and image textures
    /// included; cut-out holes skipped); zero on a
    /// miss.
    pub albedo: Vec<Vec3>,
}

impl Aovs {
    /// Traces one ray through the centre of every pixel of `region` of a `width` x
    /// `height` image.
    pub fn render(
        scene: &Scene,
        accel: &SceneAccel,
        width: u32,
        height: u32,
        region: PixelBounds,
    ) -> Aovs {
        let frame = scene.camera_frame(width, height);
        let mut out = Aovs::default();
        let cutouts = super::texturing::has_cutouts(scene);
        for y in region.y0..region.y1 {
            for x in region.x0..region.x1 {
                let ray = frame.ray(x as f32 + 0.5, y as f32 + 0.5);
                let hit = accel.closest_hit(&ray).and_then(|h| {
                    if cutouts {
                        super::texturing::solid_hit(scene, accel, &ray, h).0
                    } else {
                        Some(h)
                    }
                });
                match hit {
                    Some(hit) => {
                        let si = SurfaceInteraction::new(scene, &ray, &hit);
                        let m = &scene.materials[si.material as usize];
                        out.depth.push(hit.t);
                        out.normal.push(si.n_shading);
                        // The winding normal, as the shader uses it (checker cells).
                        let outward = if si.front_face {
                            si.n_geometric
                        } else {
                            -si.n_geometric
                        };
                        let (albedo, _) = m.colours_on_surface(si.p, si.p_error, outward, si.uv);
                        out.albedo.push(albedo);
                    }
                    None => {
                        out.depth.push(f32::INFINITY);
                        out.normal.push(Vec3::ZERO);
                        out.albedo.push(Vec3::ZERO);
                    }
                }
            }
        }
        out
    }

    /// As EXR channels: `depth.Z`, `normal.X/Y/Z`, `albedo.R/G/B`.
    pub fn channels(&self) -> Vec<ExtraChannel> {
        let mut v = vec![ExtraChannel {
            name: "depth.Z".into(),
            values: self.depth.clone(),
        }];
        for (layer, data, names) in [
            ("normal", &self.normal, ["X", "Y", "Z"]),
            ("albedo", &self.albedo, ["R", "G", "B"]),
        ] {
            for (k, c) in names.iter().enumerate() {
                v.push(ExtraChannel {
                    name: format!("{layer}.{c}"),
                    values: data.iter().map(|p| p[k]).collect(),
                });
            }
        }
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::AccelKind;
    use crate::scene::{Camera, Material, SceneBuilder};

    /// A unit sphere at the origin seen from z = 5 on a 3x3 image: the centre pixel's
    /// ray is exactly -z (sx = sy = 0), the corners miss (they pass 1.6 from the axis).
    #[test]
    fn centre_pixel_sees_the_sphere_at_known_depth_normal_and_albedo() {
        let mut b = SceneBuilder::new();
        let m = b.add_material(Material {
            diffuse: Vec3::new(0.2, 0.4, 0.6),
            ..Material::default()
        });
        b.add_sphere(Vec3::ZERO, 1.0, m);
        b.camera = Some(Camera {
            eye: Vec3::new(0.0, 0.0, 5.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            vfov_deg: 40.0,
        });
        let scene = b.finish().unwrap();
        let accel = SceneAccel::build(&scene, AccelKind::Bvh4);
        let aovs = Aovs::render(&scene, &accel, 3, 3, PixelBounds::full(3, 3));
        assert_eq!(aovs.depth.len(), 9);
        // Depth 5 - 1 = 4: the sphere test rounds to a few ulps of 4 (2.4e-7 each);
        // 1e-5 is far below any wrong answer (a depth off by a radius is 1).
        assert!((aovs.depth[4] - 4.0).abs() < 1e-5, "{}", aovs.depth[4]);
        assert!((aovs.normal[4] - Vec3::Z).abs().max_element() < 1e-5);
        assert_eq!(aovs.albedo[4], Vec3::new(0.2, 0.4, 0.6));
        for corner in [0, 2, 6, 8] {
            assert_eq!(aovs.depth[corner], f32::INFINITY);
            assert_eq!(aovs.normal[corner], Vec3::ZERO);
            assert_eq!(aovs.albedo[corner], Vec3::ZERO);
        }
        let names: Vec<String> = aovs.channels().into_iter().map(|c| c.name).collect();
        assert_eq!(
            names,
            [
                "depth.Z", "normal.X", "normal.Y", "normal.Z", "albedo.R", "albedo.G", "albedo.B"
            ]
        );
        assert_eq!(aovs.channels()[6].values[4], 0.6);
    }
}

//! Film: f32 accumulation, tone mapping, image output and error metrics.

use glam::Vec3;

/// Linear RGB radiance per pixel, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Vec3>,
}

impl Film {
    pub fn new(width: u32, height: u32) -> Self {
        Film {
            width,
            height,
            pixels: vec![Vec3::ZERO; width as usize * height as usize],
        }
    }

    pub fn get(&self, x: u32, y: u32) -> Vec3 {
        self.pixels[(y * self.width + x) as usize]
    }
}

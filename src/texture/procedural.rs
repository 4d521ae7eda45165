//! Procedural images rendered into a texture at load time, so that a shipped scene
//! needs no image file: a checkerboard, running-bond bricks and tileable value noise.

use super::Texture;
use glam::{Vec3, Vec4};
use std::path::PathBuf;

/// Which pattern a [`Procedural`] texture draws.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ProceduralKind {
    /// `cells x cells` squares alternating `a` and `b`, starting with `a` at the top left.
    Checker,
    /// `cells` rows of bricks (colour `a`, twice as wide as high, every other row
    /// shifted by half a brick) in mortar (colour `b`) an eighth of a row wide.
    Bricks,
    /// Value noise (Perlin's lattice noise with smoothstep interpolation, "An Image
    /// Synthesizer", SIGGRAPH 1985) summed over four octaves, base frequency `cells`
    /// lattice cells across the image, wrapping so the image tiles without seams;
    /// blends from `a` (0) to `b` (1).
    Noise,
}

impl ProceduralKind {
    pub fn parse(s: &str) -> Option<ProceduralKind> {
        match s {
            "checker" => Some(ProceduralKind::Checker),
            "bricks" => Some(ProceduralKind::Bricks),
            "noise" => Some(ProceduralKind::Noise),
            _ => None,
        }
    }
}

/// A procedural texture description: a `size x size` image of a pattern in two
/// linear colours.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Procedural {
    pub kind: ProceduralKind,
    pub size: u32,
    pub a: Vec3,
    pub b: Vec3,
    /// Checker squares per side, brick rows, or noise lattice cells per side.
    pub cells: u32,
    pub seed: u32,
}

impl Procedural {
    /// A key naming exactly this description, for the texture cache.
    pub fn key(&self) -> String {
        format!("{self:?}")
    }

    /// Renders the image (texel centres sampled, no antialiasing: patterns are
    /// aligned to whole texels when `size` is a multiple of the cell count).
    pub fn render(&self) -> Texture {
        let n = self.size.max(1);
        let cells = self.cells.max(1);
        let mut texels = Vec::with_capacity(n as usize * n as usize);
        for y in 0..n {
            for x in 0..n {
                let w = match self.kind {
                    ProceduralKind::Checker => {
                        let (cx, cy) = (
                            x as u64 * cells as u64 / n as u64,
                            y as u64 * cells as u64 / n as u64,
                        );
                        ((cx + cy) % 2) as f32
                    }
                    ProceduralKind::Bricks => brick_mortar(x, y, n, cells),
                    ProceduralKind::Noise => {
                        let p = ((x as f32 + 0.5) / n as f32, (y as f32 + 0.5) / n as f32);
                        fbm(p, cells, self.seed)
                    }
                };
                let c = self.a * (1.0 - w) + self.b * w;
                texels.push(Vec4::new(c.x, c.y, c.z, 1.0));
            }
        }
        Texture::from_texels(
            n,
            n,
            texels,
            PathBuf::from(format!("<procedural {:?}>", self.kind)),
        )
    }
}

/// 1 in the mortar, 0 on a brick.
fn brick_mortar(x: u32, y: u32, n: u32, rows: u32) -> f32 {
    let row_h = n as f32 / rows as f32;
    let brick_w = 2.0 * row_h;
    let mortar = (row_h / 8.0).max(1.0);
    let (fx, fy) = (x as f32 + 0.5, y as f32 + 0.5);
    let row = (fy / row_h).floor();
    let in_row = fy - row * row_h;
    let shift = if row as i64 % 2 == 1 {
        brick_w / 2.0
    } else {
        0.0
    };
    let bx = (fx + shift).rem_euclid(brick_w);
    if in_row < mortar || bx < mortar {
        1.0
    } else {
        0.0
    }
}

/// Integer hash of a lattice point (Wang-style mixing), to [0, 1).
fn lattice(ix: u32, iy: u32, seed: u32) -> f32 {
    let mut h = ix.wrapping_mul(0x8da6_b343)
        ^ iy.wrapping_mul(0xd816_3841)
        ^ seed.wrapping_mul(0xcb1a_b31f);
    h ^= h >> 15;
    h = h.wrapping_mul(0x2c1b_3c6d);
    h ^= h >> 12;
    h = h.wrapping_mul(0x297a_2d39);
    h ^= h >> 15;
    (h >> 8) as f32 / (1u32 << 24) as f32
}

/// Value noise at `p` in [0, 1)², `period` lattice cells across, wrapping.
fn value_noise(p: (f32, f32), period: u32, seed: u32) -> f32 {
    let (x, y) = (p.0 * period as f32, p.1 * period as f32);
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let s = |t: f32| t * t * (3.0 - 2.0 * t);
    let (sx, sy) = (s(fx), s(fy));
    let wrap = |i: f32| (i as i64).rem_euclid(period as i64) as u32;
    let (ix0, iy0) = (wrap(x0), wrap(y0));
    let (ix1, iy1) = (wrap(x0 + 1.0), wrap(y0 + 1.0));
    let top = lattice(ix0, iy0, seed) * (1.0 - sx) + lattice(ix1, iy0, seed) * sx;
    let bottom = lattice(ix0, iy1, seed) * (1.0 - sx) + lattice(ix1, iy1, seed) * sx;
    top * (1.0 - sy) + bottom * sy
}

/// Four octaves of value noise, each twice the frequency and half the amplitude of the
/// last, normalised to [0, 1].
fn fbm(p: (f32, f32), cells: u32, seed: u32) -> f32 {
    let (mut sum, mut amp, mut norm) = (0.0, 1.0, 0.0);
    for octave in 0..4u32 {
        sum += amp * value_noise(p, cells << octave, seed.wrapping_add(octave));
        norm += amp;
        amp *= 0.5;
    }
    sum / norm
}

#[cfg(test)]
mod tests {
    use super::*;

    fn make(kind: ProceduralKind, size: u32, cells: u32) -> Texture {
        Procedural {
            kind,
            size,
            a: Vec3::new(1.0, 0.0, 0.0),
            b: Vec3::new(0.0, 0.0, 1.0),
            cells,
            seed: 7,
        }
        .render()
    }

    #[test]
    fn checker_alternates_per_cell() {
        let t = make(ProceduralKind::Checker, 8, 4); // 2 x 2 texels per square
        let red = Vec4::new(1.0, 0.0, 0.0, 1.0);
        let blue = Vec4::new(0.0, 0.0, 1.0, 1.0);
        assert_eq!(t.texel(0, 0), red);
        assert_eq!(t.texel(1, 1), red);
        assert_eq!(t.texel(2, 0), blue);
        assert_eq!(t.texel(0, 2), blue);
        assert_eq!(t.texel(2, 2), red);
        assert_eq!(t.texel(7, 7), red);
    }

    #[test]
    fn bricks_have_mortar_lines_and_staggered_joints() {
        let t = make(ProceduralKind::Bricks, 64, 4); // rows 16 texels high, mortar 2
        let mortar = Vec4::new(0.0, 0.0, 1.0, 1.0);
        let brick = Vec4::new(1.0, 0.0, 0.0, 1.0);
        assert_eq!(t.texel(10, 0), mortar); // bed joint at the top of row 0
        assert_eq!(t.texel(10, 8), brick);
        assert_eq!(t.texel(0, 8), mortar); // head joint of row 0 at x = 0
        assert_eq!(t.texel(0, 24), brick); // row 1 is shifted by half a brick
        assert_eq!(t.texel(16, 24), mortar);
    }

    #[test]
    fn noise_is_in_range_varies_and_tiles() {
        let t = make(ProceduralKind::Noise, 64, 4);
        let w: Vec<f32> = t.texels.iter().map(|c| c.z).collect();
        assert!(w.iter().all(|x| (0.0..=1.0).contains(x)));
        let (lo, hi) = w
            .iter()
            .fold((1f32, 0f32), |(l, h), x| (l.min(*x), h.max(*x)));
        assert!(hi - lo > 0.3, "noise range {lo}..{hi}");
        // Seamless: the step across the wrap (last column to first) is no larger than
        // the largest step between neighbours inside the image.
        let step = |x0: u32, x1: u32, y: u32| (t.texel(x0, y).z - t.texel(x1, y).z).abs();
        let inner = (0..64)
            .flat_map(|y| (0..63).map(move |x| (x, y)))
            .map(|(x, y)| step(x, x + 1, y))
            .fold(0f32, f32::max);
        let across = (0..64).map(|y| step(63, 0, y)).fold(0f32, f32::max);
        assert!(across <= inner, "across the seam {across}, inside {inner}");
    }
}

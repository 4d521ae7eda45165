//! Bilinear texture lookup.

use super::{Texture, WrapMode};
use glam::{Vec2, Vec4};

/// The bilinearly filtered texture value at `uv` (linear RGBA).
///
/// Texel `(x, y)` (row 0 at the top) has its centre at
/// `uv = ((x + 0.5) / width, 1 - (y + 0.5) / height)`: `v` points up, as OBJ `vt`
/// coordinates do, and rows are stored top down, as image files are. A lookup at a
/// texel centre returns that texel exactly (for power-of-two sizes, where the centre
/// is exact in f32); between centres it blends the four nearest texels, each index
/// folded into the image by `wrap`. A non-finite `uv` reads texel (0, 0) of the
/// wrapped grid rather than producing NaN.
pub fn bilinear(tex: &Texture, uv: Vec2, wrap: WrapMode) -> Vec4 {
    let uv = if uv.is_finite() { uv } else { Vec2::ZERO };
    // f64: keeps `u * width - 0.5` exact for any f32 `u` and image side below 2^28,
    // so the texel-centre property above holds without a rounding step.
    let x = uv.x as f64 * tex.width as f64 - 0.5;
    let y = (1.0 - uv.y as f64) * tex.height as f64 - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
    let (x0, y0) = (x0 as i64, y0 as i64);
    let xa = wrap.texel(x0, tex.width);
    let xb = wrap.texel(x0 + 1, tex.width);
    let ya = wrap.texel(y0, tex.height);
    let yb = wrap.texel(y0 + 1, tex.height);
    let top = tex.texel(xa, ya) * (1.0 - fx) + tex.texel(xb, ya) * fx;
    let bottom = tex.texel(xa, yb) * (1.0 - fx) + tex.texel(xb, yb) * fx;
    top * (1.0 - fy) + bottom * fy
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    /// 4 x 2 texels, each with a distinct value: texel (x, y) = (x, y, 10 x + y, 1).
    fn grid() -> Texture {
        let texels = (0..2)
            .flat_map(|y| {
                (0..4).map(move |x| Vec4::new(x as f32, y as f32, (10 * x + y) as f32, 1.0))
            })
            .collect();
        Texture::from_texels(4, 2, texels, PathBuf::from("grid"))
    }

    fn centre(t: &Texture, x: u32, y: u32) -> Vec2 {
        Vec2::new(
            (x as f32 + 0.5) / t.width as f32,
            1.0 - (y as f32 + 0.5) / t.height as f32,
        )
    }

    #[test]
    fn texel_centres_return_the_texel_exactly() {
        let t = grid();
        for wrap in [WrapMode::Repeat, WrapMode::Clamp, WrapMode::Mirror] {
            for y in 0..2 {
                for x in 0..4 {
                    assert_eq!(
                        bilinear(&t, centre(&t, x, y), wrap),
                        t.texel(x, y),
                        "{x} {y}"
                    );
                }
            }
        }
    }

    #[test]
    fn midway_between_centres_is_the_mean() {
        let t = grid();
        // between texels (1, 0) and (2, 0): u = 0.5, v at row 0's centre
        let m = bilinear(&t, Vec2::new(0.5, 0.75), WrapMode::Repeat);
        assert_eq!(m, (t.texel(1, 0) + t.texel(2, 0)) * 0.5);
        // the middle of four texels (1..2, 0..1): u = 0.5, v = 0.5
        let m = bilinear(&t, Vec2::new(0.5, 0.5), WrapMode::Repeat);
        let mean = (t.texel(1, 0) + t.texel(2, 0) + t.texel(1, 1) + t.texel(2, 1)) * 0.25;
        assert_eq!(m, mean);
    }

    #[test]
    fn wrap_modes_at_minus_a_quarter_and_one_and_a_quarter() {
        let t = grid();
        // On a 4-wide image u = -0.25 is x = u * 4 - 0.5 = -1.5 and u = 1.25 is
        // x = 4.5: both midway between two texel centres outside the image.
        let v = 0.75; // row 0's centre
        let at = |u: f32, w| bilinear(&t, Vec2::new(u, v), w);
        let tx = |x| t.texel(x, 0);
        // x = -1.5: texels -2 and -1, half each
        assert_eq!(at(-0.25, WrapMode::Repeat), (tx(2) + tx(3)) * 0.5);
        assert_eq!(at(-0.25, WrapMode::Clamp), tx(0));
        assert_eq!(at(-0.25, WrapMode::Mirror), (tx(1) + tx(0)) * 0.5);
        // x = 4.5: texels 4 and 5
        assert_eq!(at(1.25, WrapMode::Repeat), (tx(0) + tx(1)) * 0.5);
        assert_eq!(at(1.25, WrapMode::Clamp), tx(3));
        assert_eq!(at(1.25, WrapMode::Mirror), (tx(3) + tx(2)) * 0.5);
        // and repeat is periodic: u + 1 reads what u reads
        assert_eq!(at(1.25, WrapMode::Repeat), at(0.25, WrapMode::Repeat));
    }

    #[test]
    fn non_finite_uv_reads_a_finite_value() {
        let t = grid();
        for uv in [Vec2::NAN, Vec2::new(f32::INFINITY, 0.0)] {
            assert!(bilinear(&t, uv, WrapMode::Repeat).is_finite());
        }
    }
}

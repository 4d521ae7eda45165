//! A decoded texture image: linear float RGBA, decoded by the `image` crate (PNG,
//! JPEG, TGA, Radiance HDR, OpenEXR).

use crate::error::{Error, Result};
use crate::film::srgb_to_linear;
use glam::Vec4;
use std::path::{Path, PathBuf};

/// How the integer channels of an image file are read.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Encoding {
    /// Colour maps (`map_Kd`, `map_Ks`, TOML `texture`): 8- and 16-bit RGB is sRGB
    /// encoded and is linearised on load (IEC 61966-2-1). Float images (HDR, EXR) are
    /// already linear and are kept as they are. Alpha is always linear.
    Srgb,
    /// Data maps (`map_d` cut-outs): every channel is taken as stored, divided by the
    /// largest code (255 or 65535).
    Linear,
}

/// An image in linear float RGBA, row-major, row 0 at the top of the image (v = 1;
/// texture coordinates have v = 0 at the bottom, as in OBJ `vt`).
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    pub width: u32,
    pub height: u32,
    pub texels: Vec<Vec4>,
    /// Whether the file had an alpha channel (else alpha is 1 everywhere).
    pub has_alpha: bool,
    /// The file it came from (or a procedural description), for messages.
    pub source: PathBuf,
}

impl Texture {
    /// A texture from texels already in linear RGBA. `texels.len()` must be
    /// `width * height`, both positive.
    pub fn from_texels(width: u32, height: u32, texels: Vec<Vec4>, source: PathBuf) -> Self {
        assert!(width > 0 && height > 0 && texels.len() == width as usize * height as usize);
        let has_alpha = texels.iter().any(|t| t.w != 1.0);
        Texture {
            width,
            height,
            texels,
            has_alpha,
            source,
        }
    }

    /// The texel in column `x`, row `y` (row 0 at the top).
    #[inline]
    pub fn texel(&self, x: u32, y: u32) -> Vec4 {
        self.texels[y as usize * self.width as usize + x as usize]
    }

    /// Reads and decodes an image file. A file that cannot be read or decoded (missing,
    /// truncated, not an image) is an error naming the file.
    pub fn load(path: &Path, encoding: Encoding) -> Result<Texture> {
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        Self::decode(&bytes, path, encoding)
    }

    /// Decodes an image file already in memory; `path` names it in errors and its
    /// extension helps guess the format (the content decides).
    pub fn decode(bytes: &[u8], path: &Path, encoding: Encoding) -> Result<Texture> {
        let bad = |msg: String| Error::input(path, 0, 0, format!("cannot read texture: {msg}"));
        let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes));
        if let Ok(f) = image::ImageFormat::from_path(path) {
            reader.set_format(f);
        }
        let reader = reader
            .with_guessed_format()
            .map_err(|e| bad(e.to_string()))?;
        if reader.format().is_none() {
            return Err(bad(
                "unknown image format (expected PNG, JPEG, TGA, HDR or EXR)".into(),
            ));
        }
        let img = reader.decode().map_err(|e| bad(e.to_string()))?;
        let (width, height) = (img.width(), img.height());
        if width == 0 || height == 0 {
            return Err(bad(format!("the image is {width} x {height} pixels")));
        }
        let float = matches!(
            img,
            image::DynamicImage::ImageRgb32F(_) | image::DynamicImage::ImageRgba32F(_)
        );
        let has_alpha = img.color().has_alpha();
        let rgba = img.into_rgba32f();
        let linearise = encoding == Encoding::Srgb && !float;
        let texels = rgba
            .pixels()
            .map(|p| {
                let [r, g, b, a] = p.0;
                if linearise {
                    Vec4::new(srgb_to_linear(r), srgb_to_linear(g), srgb_to_linear(b), a)
                } else {
                    Vec4::new(r, g, b, a)
                }
            })
            .collect::<Vec<_>>();
        if let Some(i) = texels.iter().position(|t| !t.is_finite()) {
            return Err(bad(format!(
                "texel ({}, {}) is not finite",
                i as u32 % width,
                i as u32 / width
            )));
        }
        Ok(Texture {
            width,
            height,
            texels,
            has_alpha,
            source: path.to_path_buf(),
        })
    }

    /// The scalar a cut-out map holds at a texel: its alpha if the file has an alpha
    /// channel, else the mean of its colour channels (a grey mask, as MTL `map_d`
    /// files usually are).
    #[inline]
    pub fn coverage_of(&self, t: Vec4) -> f32 {
        if self.has_alpha {
            t.w
        } else {
            (t.x + t.y + t.z) / 3.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn png(path: &Path, w: u32, h: u32, px: &[[u8; 4]]) {
        let img = image::RgbaImage::from_fn(w, h, |x, y| image::Rgba(px[(y * w + x) as usize]));
        img.save(path).unwrap();
    }

    #[test]
    fn png_colour_is_linearised_and_alpha_is_not() {
        let dir = tempdir("png");
        let p = dir.join("t.png");
        png(&p, 2, 1, &[[255, 128, 0, 64], [10, 20, 30, 255]]);
        let t = Texture::load(&p, Encoding::Srgb).unwrap();
        assert_eq!((t.width, t.height), (2, 1));
        assert!(t.has_alpha);
        let a = t.texel(0, 0);
        assert_eq!(a.x, 1.0);
        assert_eq!(a.y, srgb_to_linear(128.0 / 255.0));
        assert_eq!(a.z, 0.0);
        assert_eq!(a.w, 64.0 / 255.0);
        let d = Texture::load(&p, Encoding::Linear).unwrap();
        assert_eq!(d.texel(0, 0).y, 128.0 / 255.0);
        assert_eq!(d.coverage_of(d.texel(0, 0)), 64.0 / 255.0);
    }

    #[test]
    fn hdr_is_kept_linear() {
        let dir = tempdir("hdr");
        let p = dir.join("t.hdr");
        let img = image::Rgb32FImage::from_fn(1, 1, |_, _| image::Rgb([2.0, 0.5, 0.25]));
        img.save(&p).unwrap();
        let t = Texture::load(&p, Encoding::Srgb).unwrap();
        // Radiance HDR stores an 8-bit mantissa per channel with a shared exponent:
        // these three values are exact in it.
        assert_eq!(t.texel(0, 0), Vec4::new(2.0, 0.5, 0.25, 1.0));
        assert!(!t.has_alpha);
    }

    #[test]
    fn corrupt_and_missing_files_are_errors_naming_the_file() {
        let dir = tempdir("corrupt");
        let p = dir.join("broken.png");
        std::fs::write(&p, b"\x89PNG\r\n\x1a\nnot really").unwrap();
        let e = Texture::load(&p, Encoding::Srgb).unwrap_err().to_string();
        assert!(
            e.contains("broken.png") && e.contains("cannot read texture"),
            "{e}"
        );
        let e = Texture::load(&dir.join("nope.png"), Encoding::Srgb)
            .unwrap_err()
            .to_string();
        assert!(e.contains("nope.png"), "{e}");
    }

    fn tempdir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!(
            "packet-render-texture-{name}-{}",
            std::process::id()
        ));
        std::fs::create_dir_all(&d).unwrap();
        d
    }
}

//! The partial image: a region of a frame and a slice of its samples, as exact filter
//! sums per pixel, so that parts rendered apart (`--crop`, `--tile`, `--sample-range`)
//! merge into the bits of one render. The format is specified in docs/distributed.md;
//! in short (all integers little-endian):
//!
//! | field | type |
//! |---|---|
//! | magic `PKRPART\0` | 8 bytes |
//! | version (1) | u32 |
//! | full image width, height | u32, u32 |
//! | pixel bounds x0, x1, y0, y1 (half-open) | 4 x u32 |
//! | eye-sample range begin, end; spp of the frame | 3 x u32 |
//! | seed | u64 |
//! | fingerprint of the scene and options | u64 |
//! | description length, description (UTF-8) | u32, bytes |
//! | pixel data length | u64 |
//! | pixel records, row-major over the bounds | bytes |
//! | FNV-1a 64 of every byte before it | u64 |
//!
//! A pixel record is the eye-sample count (u32) followed by seven exact sums
//! ([`PixelSums`]: `Σ w·L` for r, g, b, `Σ w`, `Σ L` for r, g, b), each as a sign byte
//! (0 or 1), the index of its lowest non-zero 32-bit limb (u8), the number of limbs
//! (u8, 0 for zero) and the limbs (u32 each) of the magnitude, bit 0 worth 2^-149.

use super::exact_sum::{ExactSum, LIMBS};
use super::output::write_atomic;
use super::pixel_sums::PixelSums;
use crate::error::{Error, Result};
use crate::integrator::region::PixelBounds;
use std::io::Write;
use std::ops::Range;
use std::path::Path;

/// File extension of partial images.
pub const EXTENSION: &str = "partial";
const MAGIC: &[u8; 8] = b"PKRPART\0";
const VERSION: u32 = 1;
/// Bytes before the description.
const FIXED_HEADER: usize = 8 + 4 + 8 + 16 + 12 + 8 + 8 + 4;

/// Whether `path` names a partial image (by its `.partial` extension).
pub fn is_partial_path(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case(EXTENSION))
}

/// What a part is a part of, and which part it is.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PartialHeader {
    /// Size of the full frame.
    pub width: u32,
    pub height: u32,
    /// The pixels this part holds.
    pub bounds: PixelBounds,
    /// The eye samples of each pixel this part holds, of `0..spp`.
    pub samples: Range<u32>,
    pub spp: u32,
    pub seed: u64,
    /// Hash of the scene's contents and of every option that changes a pixel's value
    /// (see [`fingerprint`]); parts with different fingerprints never merge.
    pub fingerprint: u64,
    /// Human-readable scene and options, shown when parts do not match.
    pub description: String,
}

/// A part of a frame: header and encoded pixel records.
#[derive(Clone, Debug, PartialEq)]
pub struct PartialImage {
    pub header: PartialHeader,
    /// `bounds.area()` records, row-major (see the module documentation).
    pub pixels: Vec<u8>,
}

/// FNV-1a, 64 bits (Fowler, Noll, Vo): a fixed, portable hash; std's `DefaultHasher`
/// may change between Rust releases, and parts are merged across machines.
#[derive(Clone, Copy)]
pub struct Fnv64(pub u64);

impl Default for Fnv64 {
    fn default() -> Self {
        Fnv64(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv64 {
    pub fn update(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= b as u64;
            self.0 = self.0.wrapping_mul(0x0100_0000_01b3);
        }
    }
}

impl std::fmt::Write for Fnv64 {
    fn write_str(&mut self, s: &str) -> std::fmt::Result {
        self.update(s.as_bytes());
        Ok(())
    }
}

/// The fingerprint of a render: FNV-1a over the `Debug` text of the loaded scene (every
/// float printed so that it reads back exactly, so any change to geometry, materials,
/// lights or camera changes it) and of `options`, the text of every setting that
/// changes pixel values. Streams, without building the text.
pub fn fingerprint(scene: &impl std::fmt::Debug, options: &str) -> u64 {
    use std::fmt::Write as _;
    let mut h = Fnv64::default();
    write!(h, "{scene:?}").expect("hashing cannot fail");
    h.update(&[0]);
    h.update(options.as_bytes());
    h.0
}

/// Appends the record of one pixel.
pub fn encode_pixel(p: &PixelSums, out: &mut Vec<u8>) {
    out.extend_from_slice(&p.samples.to_le_bytes());
    for s in &p.exact_sums() {
        let (negative, mag) = s.sign_magnitude();
        let lo = mag.iter().position(|&l| l != 0).unwrap_or(0);
        let hi = mag.iter().rposition(|&l| l != 0).map_or(lo, |h| h + 1);
        out.extend_from_slice(&[negative as u8, lo as u8, (hi - lo) as u8]);
        for l in &mag[lo..hi] {
            out.extend_from_slice(&l.to_le_bytes());
        }
    }
}

/// Bytes taken by the first `n` records of `bytes` (which must hold them, as the
/// renderer's own encoding does).
pub(crate) fn encoded_len(bytes: &[u8], n: usize) -> usize {
    let mut at = 0;
    for _ in 0..n {
        at += 4;
        for _ in 0..7 {
            at += 3 + 4 * bytes[at + 2] as usize;
        }
    }
    at
}

/// Decodes the record at `*at`, advancing `*at`. `Err` says what is wrong.
pub fn decode_pixel(bytes: &[u8], at: &mut usize) -> std::result::Result<PixelSums, String> {
    let mut take = |n: usize| -> std::result::Result<&[u8], String> {
        let s = bytes
            .get(*at..*at + n)
            .ok_or_else(|| format!("pixel record cut short at byte {}", *at))?;
        *at += n;
        Ok(s)
    };
    let samples = u32::from_le_bytes(take(4)?.try_into().expect("4 bytes"));
    let mut sums = [ExactSum::default(); 7];
    for s in &mut sums {
        let head = take(3)?;
        let (sign, lo, n) = (head[0], head[1] as usize, head[2] as usize);
        if sign > 1 || lo + n > LIMBS || (n == 0 && (lo != 0 || sign != 0)) {
            return Err(format!("malformed sum (sign {sign}, limbs {lo}+{n})"));
        }
        let mut mag = [0u32; LIMBS];
        for l in &mut mag[lo..lo + n] {
            *l = u32::from_le_bytes(take(4)?.try_into().expect("4 bytes"));
        }
        if n > 0 && (mag[lo] == 0 || mag[lo + n - 1] == 0) {
            return Err("sum not in canonical form".into());
        }
        *s = ExactSum::from_sign_magnitude(sign == 1, mag)
            .ok_or_else(|| "sum out of range".to_string())?;
    }
    Ok(PixelSums::from_exact_sums(sums, samples))
}

impl PartialImage {
    /// The whole file as bytes.
    pub fn to_bytes(&self) -> Vec<u8> {
        let h = &self.header;
        let mut b = Vec::with_capacity(FIXED_HEADER + h.description.len() + self.pixels.len() + 16);
        b.extend_from_slice(MAGIC);
        for v in [
            VERSION,
            h.width,
            h.height,
            h.bounds.x0,
            h.bounds.x1,
            h.bounds.y0,
            h.bounds.y1,
            h.samples.start,
            h.samples.end,
            h.spp,
        ] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b.extend_from_slice(&h.seed.to_le_bytes());
        b.extend_from_slice(&h.fingerprint.to_le_bytes());
        b.extend_from_slice(&(h.description.len() as u32).to_le_bytes());
        b.extend_from_slice(h.description.as_bytes());
        b.extend_from_slice(&(self.pixels.len() as u64).to_le_bytes());
        b.extend_from_slice(&self.pixels);
        let mut sum = Fnv64::default();
        sum.update(&b);
        b.extend_from_slice(&sum.0.to_le_bytes());
        b
    }

    /// Writes the file atomically (temporary file, then rename).
    pub fn save(&self, path: &Path) -> Result<()> {
        let bytes = self.to_bytes();
        write_atomic(path, |out| {
            out.write_all(&bytes).map_err(|e| Error::io(path, e))
        })
    }

    /// Reads and fully validates a partial image: magic, version, checksum, header
    /// consistency and every pixel record. Errors name the file.
    pub fn load(path: &Path) -> Result<PartialImage> {
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        Self::from_bytes(&bytes).map_err(|m| Error::input(path, 0, 0, m))
    }

    /// Parses and validates the bytes of a partial image.
    pub fn from_bytes(b: &[u8]) -> std::result::Result<PartialImage, String> {
        if b.len() < 8 || &b[..8] != MAGIC {
            return Err("not a packet-render partial image (bad magic)".into());
        }
        if b.len() < FIXED_HEADER + 8 + 8 {
            return Err(format!("truncated: {} bytes, not even a header", b.len()));
        }
        let (body, tail) = b.split_at(b.len() - 8);
        let mut sum = Fnv64::default();
        sum.update(body);
        let stored = u64::from_le_bytes(tail.try_into().expect("8 bytes"));
        let u32_at = |i: usize| u32::from_le_bytes(b[i..i + 4].try_into().expect("4 bytes"));
        let u64_at = |i: usize| u64::from_le_bytes(b[i..i + 8].try_into().expect("8 bytes"));
        let version = u32_at(8);
        if version != VERSION {
            return Err(format!(
                "version {version}, this build reads version {VERSION}"
            ));
        }
        if sum.0 != stored {
            return Err("corrupt or truncated: checksum mismatch".into());
        }
        let header = PartialHeader {
            width: u32_at(12),
            height: u32_at(16),
            bounds: PixelBounds {
                x0: u32_at(20),
                x1: u32_at(24),
                y0: u32_at(28),
                y1: u32_at(32),
            },
            samples: u32_at(36)..u32_at(40),
            spp: u32_at(44),
            seed: u64_at(48),
            fingerprint: u64_at(56),
            description: String::new(),
        };
        let desc_len = u32_at(64) as usize;
        let desc_end = FIXED_HEADER + desc_len;
        if desc_end + 8 > body.len() {
            return Err("truncated in the description".into());
        }
        let description = std::str::from_utf8(&b[FIXED_HEADER..desc_end])
            .map_err(|_| "description is not UTF-8".to_string())?
            .to_string();
        let pixel_len = u64_at(desc_end) as usize;
        let pixels = &body[desc_end + 8..];
        if pixels.len() != pixel_len {
            return Err(format!(
                "pixel data is {} bytes, the header says {pixel_len}",
                pixels.len()
            ));
        }
        let header = PartialHeader {
            description,
            ..header
        };
        header.check()?;
        // Every record must decode and hold the header's sample count.
        let mut at = 0;
        for i in 0..header.bounds.area() {
            let p = decode_pixel(pixels, &mut at).map_err(|m| format!("pixel record {i}: {m}"))?;
            if p.samples != header.samples.end - header.samples.start {
                return Err(format!(
                    "pixel record {i} holds {} samples, the header's range {}..{} has {}",
                    p.samples,
                    header.samples.start,
                    header.samples.end,
                    header.samples.end - header.samples.start
                ));
            }
        }
        if at != pixels.len() {
            return Err(format!(
                "{} bytes of pixel data after the last record",
                pixels.len() - at
            ));
        }
        Ok(PartialImage {
            header,
            pixels: pixels.to_vec(),
        })
    }
}

impl PartialHeader {
    /// Rejects a header whose bounds leave the image or whose sample range is empty or
    /// past `spp`.
    pub fn check(&self) -> std::result::Result<(), String> {
        let b = &self.bounds;
        if self.width == 0 || self.height == 0 {
            return Err(format!("image size {}x{}", self.width, self.height));
        }
        if b.x0 >= b.x1 || b.y0 >= b.y1 || b.x1 > self.width || b.y1 > self.height {
            return Err(format!(
                "pixel bounds {b} empty or outside the {}x{} image",
                self.width, self.height
            ));
        }
        if self.samples.start >= self.samples.end || self.samples.end > self.spp {
            return Err(format!(
                "sample range {}..{} empty or past spp {}",
                self.samples.start, self.samples.end, self.spp
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn sample_part() -> PartialImage {
        let mut pixels = Vec::new();
        for i in 0..6 {
            let mut p = PixelSums::default();
            p.add_sample(0.5, Vec3::new(i as f32, -1e-30, 3e20));
            p.add_sample(1.0, Vec3::new(0.25, 0.0, 1.0));
            encode_pixel(&p, &mut pixels);
        }
        PartialImage {
            header: PartialHeader {
                width: 8,
                height: 4,
                bounds: PixelBounds {
                    x0: 1,
                    x1: 4,
                    y0: 2,
                    y1: 4,
                },
                samples: 2..4,
                spp: 8,
                seed: 7,
                fingerprint: 0x1234,
                description: "test ✓".into(),
            },
            pixels,
        }
    }

    #[test]
    fn round_trip() {
        let part = sample_part();
        let back = PartialImage::from_bytes(&part.to_bytes()).unwrap();
        assert_eq!(back, part);
        let mut at = 0;
        let p = decode_pixel(&back.pixels, &mut at).unwrap();
        let mut expect = PixelSums::default();
        expect.add_sample(0.5, Vec3::new(0.0, -1e-30, 3e20));
        expect.add_sample(1.0, Vec3::new(0.25, 0.0, 1.0));
        assert_eq!(p.value(), expect.value());
        assert_eq!(encoded_len(&back.pixels, 6), back.pixels.len());
    }

    #[test]
    fn corrupt_input_is_refused_with_a_reason() {
        let good = sample_part().to_bytes();
        let err = |b: &[u8]| PartialImage::from_bytes(b).unwrap_err();
        assert!(err(b"P6\n").contains("bad magic"));
        assert!(err(&good[..40]).contains("truncated"));
        assert!(err(&good[..good.len() - 3]).contains("checksum"));
        let mut flipped = good.clone();
        flipped[100] ^= 1;
        assert!(err(&flipped).contains("checksum"));
        let mut v2 = good.clone();
        v2[8] = 2;
        assert!(err(&v2).contains("version 2"));
        // Consistent checksums over inconsistent contents: re-sealed edits.
        let reseal = |edit: &dyn Fn(&mut PartialImage)| {
            let mut p = sample_part();
            edit(&mut p);
            PartialImage::from_bytes(&p.to_bytes()).unwrap_err()
        };
        assert!(reseal(&|p| p.header.bounds.x1 = 9).contains("outside"));
        assert!(reseal(&|p| p.header.samples = 2..9).contains("past spp"));
        assert!(reseal(&|p| p.header.samples = 2..5).contains("holds 2 samples"));
        assert!(
            reseal(&|p| {
                p.pixels.pop();
            })
            .contains("cut short")
        );
        assert!(reseal(&|p| p.pixels.push(0)).contains("after the last record"));
        assert!(reseal(&|p| p.pixels[4] = 2).contains("malformed"));
    }
}

//! `packet-render merge`: parts of a frame (regions, sample rounds, or both) into the
//! frame. The parts must come from one render setup (image size, spp, seed, scene and
//! options fingerprint) and together hold every sample of every pixel exactly once;
//! anything else is refused with an error naming the files. Because the parts hold
//! exact filter sums, the merged frame is bit for bit the frame one process renders.

use super::Film;
use super::partial::{PartialHeader, PartialImage, decode_pixel, encode_pixel};
use super::pixel_sums::PixelSums;
use crate::error::{Error, Result};
use crate::integrator::region::PixelBounds;
use std::path::{Path, PathBuf};

/// A merged frame: the image, and the sums of every pixel over all samples (itself a
/// partial image covering the frame, for a merge of merges).
#[derive(Clone, Debug)]
pub struct Merged {
    pub film: Film,
    pub partial: PartialImage,
}

/// Loads and merges the partial images at `paths`.
pub fn merge_files(paths: &[PathBuf]) -> Result<Merged> {
    let parts = paths
        .iter()
        .map(|p| PartialImage::load(p))
        .collect::<Result<Vec<_>>>()?;
    merge(paths, &parts)
}

/// Merges `parts` (read from `paths`, for the error messages).
pub fn merge(paths: &[PathBuf], parts: &[PartialImage]) -> Result<Merged> {
    let name = |i: usize| paths[i].display().to_string();
    let refuse = |m: String| Error::parameter("merge", m);
    if parts.is_empty() {
        return Err(refuse("no parts given".into()));
    }
    let first = &parts[0].header;
    for (i, p) in parts.iter().enumerate().skip(1) {
        mismatch(first, &p.header).map_or(Ok(()), |what| {
            Err(refuse(format!(
                "{} and {} are parts of different renders: {what}",
                name(0),
                name(i)
            )))
        })?;
    }
    // Overlap: two parts sharing a pixel and a sample.
    for i in 0..parts.len() {
        for j in i + 1..parts.len() {
            let (a, b) = (&parts[i].header, &parts[j].header);
            let samples_meet = a.samples.start < b.samples.end && b.samples.start < a.samples.end;
            if a.bounds.overlaps(&b.bounds) && samples_meet {
                return Err(refuse(format!(
                    "{} (pixels {}, samples {}..{}) and {} (pixels {}, samples {}..{}) overlap",
                    name(i),
                    a.bounds,
                    a.samples.start,
                    a.samples.end,
                    name(j),
                    b.bounds,
                    b.samples.start,
                    b.samples.end
                )));
            }
        }
    }
    // Without overlaps, a pixel has all its samples exactly when the sample counts of
    // the parts covering it add up to spp.
    let (width, height, spp) = (first.width, first.height, first.spp);
    let mut film = Film::new(width, height);
    let mut cursors = vec![0usize; parts.len()];
    let mut bytes = Vec::new();
    let mut covering = Vec::new();
    for y in 0..height {
        let rows: Vec<usize> = (0..parts.len())
            .filter(|&i| (parts[i].header.bounds.y0..parts[i].header.bounds.y1).contains(&y))
            .collect();
        for x in 0..width {
            covering.clear();
            covering.extend(
                rows.iter().copied().filter(|&i| {
                    (parts[i].header.bounds.x0..parts[i].header.bounds.x1).contains(&x)
                }),
            );
            let count: u32 = covering
                .iter()
                .map(|&i| parts[i].header.samples.end - parts[i].header.samples.start)
                .sum();
            if count != spp {
                return Err(refuse(missing_message(paths, parts, &covering, x, y, spp)));
            }
            let mut sums = PixelSums::default();
            for &i in &covering {
                let p = decode_pixel(&parts[i].pixels, &mut cursors[i])
                    .map_err(|m| Error::input(&paths[i], 0, 0, m))?;
                sums.merge(&p);
            }
            film.set(x, y, sums.value());
            encode_pixel(&sums, &mut bytes);
        }
    }
    Ok(Merged {
        film,
        partial: PartialImage {
            header: PartialHeader {
                bounds: PixelBounds::full(width, height),
                samples: 0..spp,
                ..first.clone()
            },
            pixels: bytes,
        },
    })
}

/// What differs between the render setups of two parts, if anything.
fn mismatch(a: &PartialHeader, b: &PartialHeader) -> Option<String> {
    if (a.width, a.height) != (b.width, b.height) {
        return Some(format!(
            "image size {}x{} vs {}x{}",
            a.width, a.height, b.width, b.height
        ));
    }
    if a.spp != b.spp {
        return Some(format!("spp {} vs {}", a.spp, b.spp));
    }
    if a.seed != b.seed {
        return Some(format!("seed {} vs {}", a.seed, b.seed));
    }
    if a.fingerprint != b.fingerprint {
        return Some(format!(
            "scene or options differ (fingerprint {:016x}: {}; vs {:016x}: {})",
            a.fingerprint, a.description, b.fingerprint, b.description
        ));
    }
    None
}

/// The error for pixel `(x, y)`, covered by the parts `covering` whose sample counts do
/// not add up to `spp`: which sample ranges it has and which are missing.
fn missing_message(
    paths: &[PathBuf],
    parts: &[PartialImage],
    covering: &[usize],
    x: u32,
    y: u32,
    spp: u32,
) -> String {
    let mut ranges: Vec<(u32, u32, &Path)> = covering
        .iter()
        .map(|&i| {
            let s = &parts[i].header.samples;
            (s.start, s.end, paths[i].as_path())
        })
        .collect();
    ranges.sort();
    let mut gaps = Vec::new();
    let mut next = 0;
    for &(a, b, _) in &ranges {
        if a > next {
            gaps.push(format!("{next}..{a}"));
        }
        next = next.max(b);
    }
    if next < spp {
        gaps.push(format!("{next}..{spp}"));
    }
    let have: Vec<String> = ranges
        .iter()
        .map(|(a, b, p)| format!("{a}..{b} from {}", p.display()))
        .collect();
    format!(
        "missing parts: pixel ({x}, {y}) lacks samples {} of 0..{spp} (it has {})",
        gaps.join(", "),
        if have.is_empty() {
            "none".to_string()
        } else {
            have.join(", ")
        }
    )
}

//! Parts of a render: a pixel rectangle (`--crop`, `--tile I/N`) and a slice of each
//! pixel's eye samples (`--sample-range a..b`). Every pixel's samples are keyed by the
//! pixel's index in the full image and by the sample's index in the pixel, so a part
//! renders exactly the values the whole render computes for those pixels and samples.

use crate::error::{Error, Result};
use std::ops::Range;

/// A pixel rectangle `[x0, x1) x [y0, y1)` of the full image (pbrt's `--pixelbounds`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct PixelBounds {
    pub x0: u32,
    pub x1: u32,
    pub y0: u32,
    pub y1: u32,
}

impl PixelBounds {
    /// The whole `width` x `height` image.
    pub fn full(width: u32, height: u32) -> Self {
        PixelBounds {
            x0: 0,
            x1: width,
            y0: 0,
            y1: height,
        }
    }

    pub fn width(&self) -> u32 {
        self.x1 - self.x0
    }

    pub fn height(&self) -> u32 {
        self.y1 - self.y0
    }

    /// Pixels inside.
    pub fn area(&self) -> u64 {
        self.width() as u64 * self.height() as u64
    }

    /// Whether the two rectangles share a pixel.
    pub fn overlaps(&self, o: &PixelBounds) -> bool {
        self.x0 < o.x1 && o.x0 < self.x1 && self.y0 < o.y1 && o.y0 < self.y1
    }

    /// Parses `x0,x1,y0,y1` (half-open, as pbrt's `--pixelbounds`).
    pub fn parse(s: &str) -> Result<Self> {
        let bad = |m: &str| Error::parameter("crop", format!("{s:?}: {m}"));
        let v: Vec<u32> = s
            .split(',')
            .map(|p| p.trim().parse::<u32>())
            .collect::<std::result::Result<_, _>>()
            .map_err(|_| bad("expected four non-negative integers x0,x1,y0,y1"))?;
        let [x0, x1, y0, y1] = v[..] else {
            return Err(bad("expected four non-negative integers x0,x1,y0,y1"));
        };
        if x0 >= x1 || y0 >= y1 {
            return Err(bad("empty rectangle: need x0 < x1 and y0 < y1"));
        }
        Ok(PixelBounds { x0, x1, y0, y1 })
    }

    /// Rejects a rectangle that leaves the `width` x `height` image.
    pub fn check_inside(&self, width: u32, height: u32) -> Result<()> {
        if self.x0 >= self.x1 || self.y0 >= self.y1 || self.x1 > width || self.y1 > height {
            return Err(Error::parameter(
                "crop",
                format!("{self} is empty or not inside the {width}x{height} image"),
            ));
        }
        Ok(())
    }

    /// The `index`-th of `count` balanced regions of a `width` x `height` image: bands
    /// of whole rows whose heights differ by at most one (rows `floor(i*h/n)` to
    /// `floor((i+1)*h/n)`), so the regions tile the image exactly and hold equal pixel
    /// counts to within one row. `index` is 0-based, as Slurm's `SLURM_ARRAY_TASK_ID`
    /// (with `--array=0-(N-1)`) and Kubernetes' `JOB_COMPLETION_INDEX` are.
    pub fn tile(index: u32, count: u32, width: u32, height: u32) -> Result<Self> {
        if count == 0 || index >= count {
            return Err(Error::parameter(
                "tile",
                format!("{index}/{count}: need 0 <= I < N"),
            ));
        }
        if count > height {
            return Err(Error::parameter(
                "tile",
                format!("{count} tiles of a {height}-row image: at most one tile per row"),
            ));
        }
        let row = |i: u32| (i as u64 * height as u64 / count as u64) as u32;
        Ok(PixelBounds {
            x0: 0,
            x1: width,
            y0: row(index),
            y1: row(index + 1),
        })
    }
}

impl std::fmt::Display for PixelBounds {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{},{},{},{}", self.x0, self.x1, self.y0, self.y1)
    }
}

/// Parses `--tile I/N` into `(I, N)`.
pub fn parse_tile(s: &str) -> Result<(u32, u32)> {
    let bad = || Error::parameter("tile", format!("{s:?}: expected I/N, e.g. 0/4"));
    let (i, n) = s.split_once('/').ok_or_else(bad)?;
    Ok((
        i.trim().parse().map_err(|_| bad())?,
        n.trim().parse().map_err(|_| bad())?,
    ))
}

/// Parses `--sample-range a..b` (half-open, 0-based eye-sample indices).
pub fn parse_sample_range(s: &str) -> Result<Range<u32>> {
    let bad = || {
        Error::parameter(
            "sample range",
            format!("{s:?}: expected a..b with a < b, e.g. 0..16"),
        )
    };
    let (a, b) = s.split_once("..").ok_or_else(bad)?;
    let (a, b): (u32, u32) = (
        a.trim().parse().map_err(|_| bad())?,
        b.trim().parse().map_err(|_| bad())?,
    );
    if a >= b {
        return Err(bad());
    }
    Ok(a..b)
}

/// Rejects a sample range that is empty or reaches past `spp`.
pub fn check_sample_range(r: &Range<u32>, spp: u32) -> Result<()> {
    if r.start >= r.end || r.end > spp {
        return Err(Error::parameter(
            "sample range",
            format!("{}..{}: need a < b <= spp ({spp})", r.start, r.end),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_partition_the_image_in_balanced_bands() {
        for (w, h, n) in [(7, 10, 3), (5, 5, 5), (3, 100, 7), (1, 1, 1)] {
            let mut next_row = 0;
            for i in 0..n {
                let t = PixelBounds::tile(i, n, w, h).unwrap();
                assert_eq!((t.x0, t.x1, t.y0), (0, w, next_row));
                let rows = t.height();
                assert!(rows == h / n || rows == h / n + 1, "{w}x{h}/{n}: {t}");
                next_row = t.y1;
            }
            assert_eq!(next_row, h);
        }
        assert!(PixelBounds::tile(3, 3, 8, 8).is_err());
        assert!(PixelBounds::tile(0, 0, 8, 8).is_err());
        assert!(PixelBounds::tile(0, 9, 8, 8).is_err());
    }

    #[test]
    fn parsing_and_checks() {
        let c = PixelBounds::parse("1, 5,2,3").unwrap();
        assert_eq!(
            c,
            PixelBounds {
                x0: 1,
                x1: 5,
                y0: 2,
                y1: 3
            }
        );
        assert_eq!(c.area(), 4);
        assert!(c.check_inside(5, 3).is_ok());
        assert!(c.check_inside(4, 3).is_err());
        for bad in [
            "1,5,2",
            "1,5,2,3,4",
            "5,1,2,3",
            "1,5,3,3",
            "a,b,c,d",
            "-1,5,2,3",
        ] {
            assert!(PixelBounds::parse(bad).is_err(), "{bad}");
        }
        assert_eq!(parse_tile("2/8").unwrap(), (2, 8));
        assert!(parse_tile("2").is_err());
        assert_eq!(parse_sample_range("4..16").unwrap(), 4..16);
        for bad in ["4..4", "5..4", "4-16", "..4", "a..b"] {
            assert!(parse_sample_range(bad).is_err(), "{bad}");
        }
        assert!(check_sample_range(&(0..16), 16).is_ok());
        assert!(check_sample_range(&(0..17), 16).is_err());
        let a = PixelBounds::parse("0,4,0,4").unwrap();
        assert!(a.overlaps(&PixelBounds::parse("3,5,3,5").unwrap()));
        assert!(!a.overlaps(&PixelBounds::parse("4,5,0,4").unwrap()));
    }
}

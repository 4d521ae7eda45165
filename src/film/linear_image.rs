//! [`Film`]: the frame as linear RGB per pixel, with its error metrics.

use super::color::linear_to_srgb8;
use crate::error::{Error, Result};
use crate::pages::{commit_for_writing, try_zeroed_vec, zeroed_vec};
use glam::Vec3;

/// Linear RGB radiance per pixel, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Vec3>,
}

impl Film {
    /// A black frame. Its pixels come from `alloc_zeroed` (zero pages from the kernel),
    /// so making it writes nothing: the pages are touched by whoever writes them first,
    /// in parallel in the tile renderer. `vec![Vec3::ZERO; n]` filled the 9.4 MB of a
    /// 1024x768 frame serially before any tile started: 5-11 ms of the render phase
    /// (whitted_base, 1 thread, loaded machine), one thread working and one waiting.
    ///
    /// Large frames are advised for huge pages before their first touch (session 26,
    /// measured on [`advise_huge_pages`]); the dead end below was a fragmented guest.
    ///
    /// Dead end then: `madvise(MADV_HUGEPAGE)` on the frame. First touch of a fresh 4 KiB
    /// page costs 4-18 us on this VM (9.4 MB touched in 21-39 ms, 6 runs, load 7.5),
    /// and huge pages made it 1.7-2.3 ms in half the runs but 46-120 ms in the others
    /// (direct compaction; the `madvise` call itself took up to 10 ms), so the bunny
    /// frame's `resolve` stage went from 30-38 ms to 7-110 ms. `MADV_POPULATE_WRITE`
    /// on the whole frame in one call here cost as much as touching (16-28 ms, serial);
    /// per band of rows, by the thread that renders it, it saves the trap per page
    /// (`pages/populate.rs`, called from the tile renderer).
    pub fn new(width: u32, height: u32) -> Self {
        Film {
            width,
            height,
            pixels: zeroed_pixels(width as usize * height as usize),
        }
    }

    /// A black frame whose memory is mapped now, before the render that writes it: the
    /// film as a resource taken before any work starts, as the command line does after
    /// its memory check. Where the system cannot give the memory, this is the error
    /// (naming the frame and its size), not a process killed halfway through a render.
    /// The pages are mapped in parallel chunks on the caller's rayon pool
    /// (`MADV_POPULATE_WRITE`, `pages::commit_for_writing`); where the system cannot map
    /// ahead (kernels before Linux 5.14, other systems) the film is [`Film::new`]'s and
    /// its pages are mapped as it is written.
    ///
    /// Why ahead: the film is the one large array a frame writes once (9.4 MB at
    /// 1024x768), and its first touch is the part of a render that moves with the
    /// virtual machine's host, not with the work (fresh pages 1-40 us each to back).
    /// POV-Ray, our anchor, does the same: 4,589 of its 6,317 page faults on
    /// whitted 1024x768 at 2 threads (`perf record -e page-faults -c 1 -g`) fall on
    /// its main thread in its first 0.15 s, before its render threads start and outside
    /// the "Trace Time" it reports; most of them in a `memset` that grows with the
    /// pixel count, 20 bytes a pixel (its image: 1,619 / 4,499 / 16,022 pages at
    /// 512x384 / 1024x768 / 2048x1536).
    pub fn committed(width: u32, height: u32) -> Result<Self> {
        use rayon::prelude::*;
        let refused = |why: String| {
            let mib = (film_bytes(width, height) as f64) / f64::from(1 << 20);
            Error::parameter(
                "memory",
                format!(
                    "the {width}x{height} film needs {mib:.1} MiB, which the system cannot \
                     give now ({why}): render a smaller image, or in parts (--crop, --tile)"
                ),
            )
        };
        // The allocation itself may fail too (an address-space limit, a heuristic
        // overcommit that refuses it): an error here, not `Film::new`'s abort.
        let mut pixels = try_zeroed_pixels(width as usize * height as usize)
            .map_err(|_| refused("the allocation failed".into()))?;
        // Chunks of 2 MiB: a huge page each where the frame got them.
        const CHUNK: usize = (2 << 20) / std::mem::size_of::<Vec3>();
        pixels
            .par_chunks_mut(CHUNK)
            .try_for_each(|c| commit_for_writing(c).map(|_| ()))
            .map_err(|e| refused(e.to_string()))?;
        Ok(Film {
            width,
            height,
            pixels,
        })
    }

    pub fn get(&self, x: u32, y: u32) -> Vec3 {
        self.pixels[self.index(x, y)]
    }

    pub fn set(&mut self, x: u32, y: u32, value: Vec3) {
        let i = self.index(x, y);
        self.pixels[i] = value;
    }

    #[inline]
    fn index(&self, x: u32, y: u32) -> usize {
        y as usize * self.width as usize + x as usize
    }

    /// 8-bit sRGB, three bytes per pixel, row 0 first: each channel clamped to [0, 1]
    /// and encoded with the sRGB OETF (IEC 61966-2-1), not a plain 2.2 gamma, so that
    /// dark tones keep the linear toe the standard specifies.
    pub fn to_srgb8(&self) -> Vec<u8> {
        self.pixels
            .iter()
            .flat_map(|p| p.to_array())
            .map(linear_to_srgb8)
            .collect()
    }

    /// Mean radiance over all pixels (zero for an empty film).
    pub fn mean(&self) -> Vec3 {
        if self.pixels.is_empty() {
            return Vec3::ZERO;
        }
        let sum = self
            .pixels
            .iter()
            .fold(glam::DVec3::ZERO, |acc, p| acc + p.as_dvec3());
        (sum / self.pixels.len() as f64).as_vec3()
    }

    /// `Ok` when `other` has this film's size; the error every comparison of two films
    /// gives otherwise.
    pub fn same_size(&self, other: &Film) -> Result<()> {
        if (self.width, self.height) != (other.width, other.height) {
            return Err(Error::parameter(
                "film",
                format!(
                    "cannot compare a {}x{} film with a {}x{} film",
                    self.width, self.height, other.width, other.height
                ),
            ));
        }
        Ok(())
    }

    /// Root-mean-square difference over every channel of every pixel, in f64 so that
    /// the sum of many small squares does not lose digits. Films of different sizes are
    /// an error, not a number.
    pub fn rmse(&self, other: &Film) -> Result<f64> {
        self.same_size(other)?;
        if self.pixels.is_empty() {
            return Ok(0.0);
        }
        let sum: f64 = self
            .pixels
            .iter()
            .zip(&other.pixels)
            .map(|(a, b)| (a.as_dvec3() - b.as_dvec3()).length_squared())
            .sum();
        Ok((sum / (3 * self.pixels.len()) as f64).sqrt())
    }

    /// Peak signal-to-noise ratio in dB against a peak of 1.0 (display white in linear
    /// radiance); `+inf` for identical films.
    pub fn psnr(&self, other: &Film) -> Result<f64> {
        let rmse = self.rmse(other)?;
        Ok(if rmse == 0.0 {
            f64::INFINITY
        } else {
            -20.0 * rmse.log10()
        })
    }
}

// Three f32 lanes and nothing else, so all-zero bytes are `Vec3::ZERO`.
const _: () = assert!(std::mem::size_of::<Vec3>() == 12 && std::mem::align_of::<Vec3>() == 4);

/// Bytes of a `width` x `height` film's pixels.
fn film_bytes(width: u32, height: u32) -> usize {
    width as usize * height as usize * std::mem::size_of::<Vec3>()
}

/// `n` black pixels, allocated zeroed rather than filled (`pages::zeroed_vec`: advised
/// for huge pages before their first touch, measured on `pages::advise_huge_pages`);
/// aborts where the memory cannot be had (as `Vec` does).
fn zeroed_pixels(n: usize) -> Vec<Vec3> {
    // SAFETY: all-zero bytes are a valid Vec3 (0.0 thrice; asserted above).
    unsafe { zeroed_vec(n) }
}

/// [`zeroed_pixels`], or the layout the allocator refused.
fn try_zeroed_pixels(n: usize) -> std::result::Result<Vec<Vec3>, std::alloc::Layout> {
    // SAFETY: all-zero bytes are a valid Vec3 (asserted above).
    unsafe { try_zeroed_vec(n) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::film::luminance;

    /// A committed film is black and the region's size, like a fresh one, and on
    /// Linux (5.14 and later) every page its pixels lie in is resident before anything
    /// writes it (`mincore`); 1000x700 spans several 2 MiB chunks and ends inside one.
    #[test]
    fn committed_film_is_black_and_mapped() {
        let (w, h) = (1000, 700);
        let film = Film::committed(w, h).expect("8 MB of film");
        assert_eq!(film, Film::new(w, h));
        #[cfg(target_os = "linux")]
        {
            // SAFETY: `sysconf` has no preconditions.
            let page = unsafe { libc::sysconf(libc::_SC_PAGESIZE) } as usize;
            let start = film.pixels.as_ptr() as usize;
            let end = start + film_bytes(w, h);
            let first = start / page * page;
            let pages = (end - first).div_ceil(page);
            let mut vec = vec![0u8; pages];
            // SAFETY: the range covers the pages of the film's live allocation.
            let rc = unsafe {
                libc::mincore(first as *mut libc::c_void, pages * page, vec.as_mut_ptr())
            };
            assert_eq!(rc, 0, "mincore");
            let mut probe = [0u8; 1];
            if crate::pages::commit_for_writing(&mut probe[..]).expect("probe") {
                let missing = vec.iter().filter(|v| *v & 1 == 0).count();
                assert_eq!(missing, 0, "{missing} of {pages} pages not resident");
            } else {
                eprintln!("skipped the residency check: no MADV_POPULATE_WRITE here");
            }
        }
    }

    #[test]
    fn error_metrics() {
        let mut a = Film::new(4, 3);
        a.set(1, 2, Vec3::new(0.5, 0.25, 1.0));
        assert_eq!(a.rmse(&a).unwrap(), 0.0);
        assert_eq!(a.psnr(&a).unwrap(), f64::INFINITY);
        let mut b = a.clone();
        // One channel of one pixel off by 0.6: rmse = sqrt(0.36 / 36) = 0.1, PSNR 20 dB.
        b.set(0, 0, Vec3::new(0.6, 0.0, 0.0));
        assert!((a.rmse(&b).unwrap() - 0.1).abs() < 1e-7);
        assert!((a.psnr(&b).unwrap() - 20.0).abs() < 1e-5);
        assert!(a.rmse(&Film::new(3, 4)).is_err());
    }

    /// The zero-allocated frame is black, every pixel, at any size (0 included), and
    /// frees like any vector (a second frame reuses the allocator without complaint).
    /// A frame of 8 MiB and more gets huge-page advice before its first touch (the
    /// mapping that holds its first whole 2 MiB page is flagged `hg`), and reads black.
    #[cfg(target_os = "linux")]
    #[test]
    fn large_frame_is_advised_for_huge_pages() {
        let film = Film::new(1024, 768);
        let inner = (film.pixels.as_ptr() as usize).next_multiple_of(2 << 20);
        let flags = crate::pages::vm_flags_at(inner).expect("the film's mapping in smaps");
        assert!(
            flags.iter().any(|f| f == "hg"),
            "film not advised: {flags:?}"
        );
        assert!(film.pixels.iter().all(|p| *p == Vec3::ZERO));
    }

    #[test]
    fn new_frame_is_black() {
        for (w, h) in [(0, 0), (1, 1), (3, 4), (1024, 768)] {
            let f = Film::new(w, h);
            assert_eq!(f.pixels.len(), (w * h) as usize);
            assert!(f.pixels.iter().all(|&p| p == Vec3::ZERO), "{w}x{h}");
            let mut g = f.clone();
            g.pixels.push(Vec3::ONE);
            assert_eq!(g.pixels.len(), (w * h) as usize + 1);
        }
    }

    #[test]
    fn mean_and_luminance() {
        let mut f = Film::new(2, 1);
        f.set(0, 0, Vec3::new(1.0, 2.0, 3.0));
        assert_eq!(f.mean(), Vec3::new(0.5, 1.0, 1.5));
        assert!((luminance(Vec3::ONE) - 1.0).abs() < 1e-6);
        assert_eq!(Film::new(0, 0).mean(), Vec3::ZERO);
    }
}

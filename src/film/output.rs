//! Image files: format by extension, written atomically.

use super::Film;
use super::tonemap::{Display8, ImageOptions};
use crate::error::{Error, Result};
use image::codecs::hdr::HdrEncoder;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};

/// Extensions [`Film::save`] understands (lower case, compared case-insensitively).
pub const SUPPORTED_EXTENSIONS: &[&str] = &["png", "hdr", "exr"];

#[derive(Clone, Copy)]
enum Format {
    /// 8-bit sRGB after exposure and tone mapping: for looking at.
    Png,
    /// Radiance RGBE, linear float: for measuring.
    Hdr,
    /// OpenEXR, linear f32 or f16, lossless: for pipelines (compositing, grading).
    Exr,
}

impl Film {
    /// Writes the film to `path` with the default [`ImageOptions`] (no exposure, clamp,
    /// 32-bit EXR); see [`Film::save_with`].
    pub fn save(&self, path: &Path) -> Result<()> {
        self.save_with(path, &ImageOptions::default())
    }

    /// Writes the film to `path`, choosing the format from the extension: `.png` (8-bit
    /// sRGB, tagged with an sRGB chunk, after `opts`' exposure and tone mapping), `.hdr`
    /// (Radiance RGBE, linear) or `.exr` (OpenEXR, linear, f32 or f16 per
    /// `opts.exr_half`, ZIP-compressed, lossless). Float outputs ignore exposure and
    /// tone mapping.
    ///
    /// The write is atomic: the image is encoded into a temporary file in the target's
    /// directory, flushed to disk, and renamed over the target. A reader never sees a
    /// half-written image, an existing file is only replaced by a complete one, and on
    /// any error the temporary file is removed, so a failed save leaves nothing behind.
    pub fn save_with(&self, path: &Path, opts: &ImageOptions) -> Result<()> {
        self.save_with_channels(path, opts, &[])
    }

    /// [`Film::save_with`] plus `extra` channels (one value per pixel each, such as
    /// the AOVs of [`crate::integrator::aov`]), which only `.exr` can hold: any other
    /// format with extra channels is an error.
    pub fn save_with_channels(
        &self,
        path: &Path,
        opts: &ImageOptions,
        extra: &[super::exr::ExtraChannel],
    ) -> Result<()> {
        let format = format_for(path)?;
        opts.validate()?;
        if !extra.is_empty() && !matches!(format, Format::Exr) {
            return Err(Error::parameter(
                "output",
                format!(
                    "{}: extra channels (AOVs) need an .exr output",
                    path.display()
                ),
            ));
        }
        write_atomic(path, |out| self.encode(out, path, format, opts, extra))
    }

    /// 8-bit sRGB codes after `opts`' exposure and tone mapping, three bytes per pixel.
    pub fn to_display8(&self, opts: &ImageOptions) -> Vec<u8> {
        let display = Display8::new(opts);
        self.pixels
            .iter()
            .flat_map(|p| p.to_array())
            .map(|c| display.code(c))
            .collect()
    }

    fn encode(
        &self,
        out: &mut BufWriter<File>,
        target: &Path,
        format: Format,
        opts: &ImageOptions,
        extra: &[super::exr::ExtraChannel],
    ) -> Result<()> {
        let image_err = |e: image::ImageError| Error::Image {
            path: target.to_path_buf(),
            message: e.to_string(),
        };
        match format {
            Format::Png => self.encode_png(out, target, opts)?,
            Format::Exr => super::exr::encode(self, extra, opts.exr_half, out, target)?,
            Format::Hdr => {
                // RGBE has no sign and no NaN: store what a display could show of such
                // values (0) rather than a garbage exponent.
                let finite = |c: f32| if c.is_finite() { c.max(0.0) } else { 0.0 };
                let rgb: Vec<image::Rgb<f32>> = self
                    .pixels
                    .iter()
                    .map(|p| image::Rgb([finite(p.x), finite(p.y), finite(p.z)]))
                    .collect();
                HdrEncoder::new(&mut *out)
                    .encode(&rgb, self.width as usize, self.height as usize)
                    .map_err(image_err)?
            }
        }
        Ok(())
    }

    /// PNG through the `png` crate rather than `image`'s encoder, which cannot write the
    /// sRGB chunk: the chunk tells viewers the codes are sRGB-encoded (IEC 61966-2-1),
    /// which they are ([`super::linear_to_srgb`]).
    fn encode_png(
        &self,
        out: &mut BufWriter<File>,
        target: &Path,
        opts: &ImageOptions,
    ) -> Result<()> {
        let png_err = |e: png::EncodingError| Error::Image {
            path: target.to_path_buf(),
            message: e.to_string(),
        };
        if self.width == 0 || self.height == 0 {
            return Err(Error::Image {
                path: target.to_path_buf(),
                message: format!("cannot write a {}x{} PNG", self.width, self.height),
            });
        }
        let mut enc = png::Encoder::new(&mut *out, self.width, self.height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
        let mut writer = enc.write_header().map_err(png_err)?;
        writer
            .write_image_data(&self.to_display8(opts))
            .map_err(png_err)?;
        writer.finish().map_err(png_err)
    }
}

/// Checks that `path` names a supported image format, so a render can refuse a bad
/// output path before doing any work.
pub fn check_image_path(path: &Path) -> Result<()> {
    format_for(path).map(|_| ())
}

/// Writes a file atomically: `write` fills a temporary file in the target's directory,
/// which is flushed to disk and renamed over `path`. A reader never sees a half-written
/// file (an interrupted render included), an existing file is only replaced by a
/// complete one, and on any error the temporary file is removed.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> Result<()>,
) -> Result<()> {
    let tmp = temp_path_for(path)?;
    let result = (|| {
        let file = create_in_flight(&tmp).map_err(|e| Error::io(path, e))?;
        let mut out = BufWriter::new(file);
        write(&mut out)?;
        let file = out
            .into_inner()
            .map_err(|e| Error::io(path, e.into_error()))?;
        // Data on disk before the rename makes it visible, or a crash could leave a
        // complete-looking name over an empty file.
        file.sync_all().map_err(|e| Error::io(path, e))?;
        rename_in_flight(&tmp, path).map_err(|e| Error::io(path, e))
    })();
    match result {
        Ok(()) => {
            sync_parent_dir(path);
            Ok(())
        }
        Err(e) => {
            // The temp file may not exist (creation failed); nothing to report then.
            let _ = std::fs::remove_file(&tmp);
            forget_in_flight(&tmp);
            Err(e)
        }
    }
}

/// Temporary files of writes in progress, so that an interrupt can remove them.
///
/// Creation and the final rename happen under this lock, and the interrupt handler
/// takes it and never releases it (it exits the process while holding it). So either
/// the handler runs first and no temporary file is ever created, or the file exists
/// and is removed (the rename of a removed file then fails), or the rename completed
/// and a complete image stays: never a truncated image and never a stray temp file.
static IN_FLIGHT: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn in_flight() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    IN_FLIGHT.lock().unwrap_or_else(|e| e.into_inner())
}

fn create_in_flight(tmp: &Path) -> std::io::Result<File> {
    let mut list = in_flight();
    let file = File::create(tmp)?;
    list.push(tmp.to_path_buf());
    Ok(file)
}

fn rename_in_flight(tmp: &Path, path: &Path) -> std::io::Result<()> {
    let mut list = in_flight();
    let r = std::fs::rename(tmp, path);
    list.retain(|p| p != tmp);
    r
}

fn forget_in_flight(tmp: &Path) {
    in_flight().retain(|p| p != tmp);
}

/// Removes the temporary files of the writes in progress that `which` selects and
/// returns how many; those writes then fail at their rename.
fn remove_in_flight(list: &mut Vec<PathBuf>, which: impl Fn(&Path) -> bool) -> usize {
    let before = list.len();
    list.retain(|p| {
        let hit = which(p);
        if hit {
            let _ = std::fs::remove_file(p);
        }
        !hit
    });
    before - list.len()
}

/// Exit status of a process stopped by SIGINT (128 + 2), as shells report it.
pub const INTERRUPTED_EXIT_CODE: i32 = 130;

/// Installs a Ctrl-C (SIGINT/SIGTERM) handler that removes the temporary files of
/// writes in progress and exits with [`INTERRUPTED_EXIT_CODE`]. Without it the default
/// action kills the process mid-write and leaves a hidden `.name.tmp-*` file behind
/// (the target itself is safe either way: it only ever appears by rename).
pub fn install_interrupt_handler() -> Result<()> {
    ctrlc::set_handler(|| {
        let mut list = in_flight();
        remove_in_flight(&mut list, |_| true);
        // Exit while still holding the lock, so no write can start or finish.
        std::mem::forget(list);
        std::process::exit(INTERRUPTED_EXIT_CODE);
    })
    .map_err(|e| Error::parameter("interrupt handler", e.to_string()))
}

fn format_for(path: &Path) -> Result<Format> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("png") => Ok(Format::Png),
        Some("hdr") => Ok(Format::Hdr),
        Some("exr") => Ok(Format::Exr),
        _ => Err(Error::parameter(
            "image format",
            format!(
                "{}: unsupported extension, expected one of .{}",
                path.display(),
                SUPPORTED_EXTENSIONS.join(", .")
            ),
        )),
    }
}

/// `dir/.name.tmp-<pid>-<n>`: in the target's directory so the rename stays on one
/// file system (and is therefore atomic), hidden, and unique per process and per call
/// so that concurrent saves never share a temporary file.
fn temp_path_for(path: &Path) -> Result<PathBuf> {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let name = path.file_name().ok_or_else(|| {
        Error::parameter(
            "output path",
            format!("{} has no file name", path.display()),
        )
    })?;
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let tmp_name = format!(".{}.tmp-{}-{n}", name.to_string_lossy(), std::process::id());
    Ok(path.with_file_name(tmp_name))
}

/// Makes the rename itself durable where the platform allows it; a failure here cannot
/// undo a completed rename, so it is not an error.
fn sync_parent_dir(path: &Path) {
    #[cfg(unix)]
    {
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        if let Ok(d) = File::open(dir) {
            let _ = d.sync_all();
        }
    }
    #[cfg(not(unix))]
    let _ = path;
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn scratch_dir(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("packet-render-film-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn entries(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    fn gradient() -> Film {
        let mut f = Film::new(5, 3);
        for y in 0..3 {
            for x in 0..5 {
                f.set(x, y, Vec3::new(x as f32 / 4.0, y as f32 / 2.0, 0.25));
            }
        }
        f
    }

    #[test]
    fn png_and_hdr_round_trip_and_leave_no_temp_files() {
        let dir = scratch_dir("roundtrip");
        let film = gradient();
        let png = dir.join("out.png");
        let hdr = dir.join("out.HDR");
        film.save(&png).unwrap();
        film.save(&hdr).unwrap();
        // Saving over an existing file replaces it.
        film.save(&png).unwrap();
        assert_eq!(entries(&dir), vec!["out.HDR", "out.png"]);

        let back = image::open(&png).unwrap().to_rgb8();
        assert_eq!(back.dimensions(), (5, 3));
        assert_eq!(back.into_raw(), film.to_srgb8());

        let back = image::open(&hdr).unwrap().to_rgb32f();
        for (a, b) in back.pixels().zip(&film.pixels) {
            // RGBE keeps 8 mantissa bits per channel relative to the largest channel.
            assert!((Vec3::from_array(a.0) - *b).abs().max_element() < 1.0 / 128.0);
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn failed_write_leaves_nothing() {
        let dir = scratch_dir("fail");
        let missing = dir.join("no-such-dir").join("out.png");
        let err = gradient().save(&missing).unwrap_err();
        assert!(
            matches!(err, Error::Io { ref path, .. } if path == &missing),
            "{err}"
        );
        assert!(entries(&dir).is_empty());

        // An encoder error (a 0x0 image) must not leave the temp file either.
        let empty = dir.join("empty.png");
        assert!(Film::new(0, 0).save(&empty).is_err());
        assert!(entries(&dir).is_empty(), "{:?}", entries(&dir));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn interrupt_during_a_write_leaves_nothing() {
        // What the Ctrl-C handler does, run from inside the write: the temp file is
        // removed, the rename then fails, and neither target nor temp file remain.
        let dir = scratch_dir("interrupt");
        let target = dir.join("out.png");
        let mut removed = 0;
        let err = write_atomic(&target, |out| {
            use std::io::Write;
            out.write_all(b"half an image").unwrap();
            out.flush().unwrap();
            assert_eq!(entries(&dir).len(), 1, "the temp file exists while writing");
            // Only this test's file: other tests write concurrently.
            removed = remove_in_flight(&mut in_flight(), |p| p.starts_with(&dir));
            Ok(())
        })
        .unwrap_err();
        assert!(removed >= 1, "the write in progress was not registered");
        assert!(matches!(err, Error::Io { .. }), "{err}");
        assert!(entries(&dir).is_empty(), "{:?}", entries(&dir));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn unknown_extension_names_the_supported_ones() {
        let dir = scratch_dir("ext");
        for name in ["out.jpg", "out"] {
            let err = gradient().save(&dir.join(name)).unwrap_err();
            let msg = err.to_string();
            assert!(
                msg.contains(".png") && msg.contains(".hdr") && msg.contains(".exr"),
                "{msg}"
            );
        }
        assert!(entries(&dir).is_empty());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    use crate::film::{ImageOptions, ToneMap};

    #[test]
    fn png_carries_an_srgb_chunk_and_the_tone_mapped_codes() {
        let dir = scratch_dir("srgb");
        let path = dir.join("out.png");
        let opts = ImageOptions {
            exposure: 1.0,
            tonemap: ToneMap::Reinhard,
            ..ImageOptions::default()
        };
        gradient().save_with(&path, &opts).unwrap();
        let decoder = png::Decoder::new(std::io::BufReader::new(File::open(&path).unwrap()));
        let mut reader = decoder.read_info().unwrap();
        assert_eq!(
            reader.info().srgb,
            Some(png::SrgbRenderingIntent::Perceptual),
            "no sRGB chunk"
        );
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let frame = reader.next_frame(&mut buf).unwrap();
        assert_eq!(&buf[..frame.buffer_size()], gradient().to_display8(&opts));
        // Exposure and Reinhard change the codes (the operator's values are checked in
        // film::tonemap's tests).
        assert_ne!(gradient().to_display8(&opts), gradient().to_srgb8());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn exposure_and_tone_mapping_leave_float_outputs_unchanged() {
        let dir = scratch_dir("floatout");
        let film = gradient();
        let opts = ImageOptions {
            exposure: 3.0,
            tonemap: ToneMap::Filmic,
            ..ImageOptions::default()
        };
        for ext in ["hdr", "exr"] {
            let plain = dir.join(format!("plain.{ext}"));
            let exposed = dir.join(format!("exposed.{ext}"));
            film.save(&plain).unwrap();
            film.save_with(&exposed, &opts).unwrap();
            assert_eq!(
                std::fs::read(&plain).unwrap(),
                std::fs::read(&exposed).unwrap(),
                ".{ext} changed with exposure"
            );
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// The R, G, B channels of the first layer of an EXR file, and whether they are half.
    fn read_exr(path: &Path) -> (Vec<[f32; 3]>, Vec<String>, bool) {
        use exr::prelude::FlatSamples;
        let image = exr::prelude::read_all_flat_layers_from_file(path).unwrap();
        let layer = &image.layer_data[0];
        let names: Vec<String> = layer
            .channel_data
            .list
            .iter()
            .map(|c| c.name.to_string())
            .collect();
        let get = |name: &str| {
            let c = layer
                .channel_data
                .list
                .iter()
                .find(|c| c.name.to_string() == name)
                .unwrap();
            match &c.sample_data {
                FlatSamples::F32(v) => (v.clone(), false),
                FlatSamples::F16(v) => (v.iter().map(|h| h.to_f32()).collect(), true),
                FlatSamples::U32(_) => panic!("u32 channel"),
            }
        };
        let ((r, half), (g, _), (b, _)) = (get("R"), get("G"), get("B"));
        let px = (0..r.len()).map(|i| [r[i], g[i], b[i]]).collect();
        (px, names, half)
    }

    #[test]
    fn exr_float_round_trips_bit_exactly() {
        let dir = scratch_dir("exr32");
        let mut film = Film::new(3, 2);
        // Values no 8-bit or RGBE format keeps: negative, tiny, huge, non-finite, and
        // an f32 with all mantissa bits set.
        let odd = [
            Vec3::new(-0.5, 1e-30, 3.0e38),
            Vec3::new(f32::INFINITY, f32::NEG_INFINITY, f32::NAN),
            Vec3::new(1.0 + f32::EPSILON, 0.1, 1.0 / 3.0),
            Vec3::new(f32::from_bits(0x3fff_ffff), 65504.0, 1e-45),
            Vec3::new(0.0, -0.0, 12345.678),
            Vec3::new(0.25, 0.5, 0.75),
        ];
        film.pixels.copy_from_slice(&odd);
        let path = dir.join("out.exr");
        film.save(&path).unwrap();
        let (back, names, half) = read_exr(&path);
        assert!(!half, "default EXR must be 32-bit float");
        assert_eq!(names, vec!["B", "G", "R"]);
        assert_eq!(back.len(), odd.len());
        for (a, b) in back.iter().zip(&odd) {
            for k in 0..3 {
                assert_eq!(a[k].to_bits(), b[k].to_bits(), "{a:?} vs {b:?}");
            }
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn exr_half_round_trips_values_representable_in_half() {
        let dir = scratch_dir("exr16");
        let mut film = Film::new(2, 2);
        // All exactly representable in binary16: 2^-24 is its smallest subnormal,
        // 65504 its largest finite, 1 + 2^-10 the neighbour of 1.
        let exact = [
            Vec3::new(0.0, 1.0, -2.5),
            Vec3::new(2f32.powi(-24), 65504.0, 1.0 + 1.0 / 1024.0),
            Vec3::new(0.1875, 1000.5, -(2f32.powi(-14))),
            Vec3::new(f32::INFINITY, 3.0, 1365.0 / 4096.0),
        ];
        film.pixels.copy_from_slice(&exact);
        let path = dir.join("half.exr");
        let opts = ImageOptions {
            exr_half: true,
            ..ImageOptions::default()
        };
        film.save_with(&path, &opts).unwrap();
        let (back, _, half) = read_exr(&path);
        assert!(half, "--exr-half must write half channels");
        for (a, b) in back.iter().zip(&exact) {
            for k in 0..3 {
                assert_eq!(a[k].to_bits(), b[k].to_bits(), "{a:?} vs {b:?}");
            }
        }
        // A value half cannot hold is rounded to nearest: 0.1 -> 0.099975586.
        film.pixels[0] = Vec3::splat(0.1);
        film.save_with(&path, &opts).unwrap();
        assert_eq!(read_exr(&path).0[0][0], 0.099_975_586);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn exr_extra_channels_round_trip_and_other_formats_refuse_them() {
        use crate::film::exr::ExtraChannel;
        use exr::prelude::FlatSamples;
        let dir = scratch_dir("exraov");
        let film = gradient();
        let depth: Vec<f32> = (0..15).map(|i| i as f32 * 0.37 + 1.0).collect();
        let mut nz = vec![f32::INFINITY; 15];
        nz[7] = -0.0;
        let extra = vec![
            ExtraChannel {
                name: "depth.Z".into(),
                values: depth.clone(),
            },
            ExtraChannel {
                name: "normal.Z".into(),
                values: nz.clone(),
            },
        ];
        let path = dir.join("aov.exr");
        film.save_with_channels(&path, &ImageOptions::default(), &extra)
            .unwrap();
        let (rgb, names, _) = read_exr(&path);
        assert_eq!(names, ["B", "G", "R", "depth.Z", "normal.Z"]);
        assert_eq!(rgb[14], film.pixels[14].to_array());
        let image = exr::prelude::read_all_flat_layers_from_file(&path).unwrap();
        let list = &image.layer_data[0].channel_data.list;
        for (ch, want) in [(&list[3], &depth), (&list[4], &nz)] {
            let FlatSamples::F32(got) = &ch.sample_data else {
                panic!("not f32")
            };
            let bits = |v: &Vec<f32>| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(got), bits(want));
        }
        // A wrong-length channel and a format without channels are errors, not files.
        let short = [ExtraChannel {
            name: "depth.Z".into(),
            values: vec![1.0; 3],
        }];
        let opts = ImageOptions::default();
        assert!(
            film.save_with_channels(&dir.join("short.exr"), &opts, &short)
                .is_err()
        );
        let err = film
            .save_with_channels(&dir.join("aov.png"), &opts, &extra)
            .unwrap_err();
        assert!(err.to_string().contains(".exr"), "{err}");
        assert_eq!(entries(&dir), ["aov.exr"]);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

//! Reading an equirectangular environment map from a file: Radiance `.hdr` through the
//! `image` crate, OpenEXR `.exr` through the `exr` crate (the first RGBA layer, the
//! largest resolution level). Errors name the file.

use crate::error::{Error, Result};
use glam::Vec3;
use std::path::Path;

/// `(width, height, texels)` of the map in `path`, row-major from the top row.
pub fn read_environment_map(path: &Path) -> Result<(usize, usize, Vec<Vec3>)> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let fail = |m: String| Error::input(path, 0, 0, m);
    if !path.is_file() {
        return Err(fail("environment map not found".into()));
    }
    match ext.as_deref() {
        Some("hdr") => {
            let img = image::ImageReader::open(path)
                .map_err(|e| Error::io(path, e))?
                .with_guessed_format()
                .map_err(|e| Error::io(path, e))?
                .decode()
                .map_err(|e| fail(format!("cannot decode the Radiance HDR map: {e}")))?
                .into_rgb32f();
            let (w, h) = (img.width() as usize, img.height() as usize);
            let texels = img.pixels().map(|p| Vec3::from_array(p.0)).collect();
            Ok((w, h, texels))
        }
        Some("exr") => {
            type Pixels = (usize, Vec<Vec3>);
            let image = exr::prelude::read_first_rgba_layer_from_file(
                path,
                |size, _| -> Pixels { (size.width(), vec![Vec3::ZERO; size.area()]) },
                |px: &mut Pixels, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                    let i = pos.y() * px.0 + pos.x();
                    px.1[i] = Vec3::new(r, g, b);
                },
            )
            .map_err(|e| fail(format!("cannot read the OpenEXR map: {e}")))?;
            let size = image.layer_data.size;
            let (_, texels) = image.layer_data.channel_data.pixels;
            Ok((size.width(), size.height(), texels))
        }
        _ => Err(fail(
            "unsupported environment map format: expected a `.hdr` (Radiance) or `.exr` (OpenEXR) file".into(),
        )),
    }
}

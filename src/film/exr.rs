//! OpenEXR output through the `exr` crate (pure Rust, maintained): linear radiance as
//! R, G, B channels of one layer, 32-bit float or 16-bit half, ZIP (lossless), plus any
//! extra named channels (arbitrary output variables such as `depth.Z`).

use super::Film;
use crate::error::{Error, Result};
use exr::prelude::{
    AnyChannel, AnyChannels, Encoding, FlatSamples, Image, Layer, LayerAttributes, SmallVec,
    WritableImage, f16,
};
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

/// One extra channel: its EXR name (`layer.channel`, e.g. `normal.X`) and one value per
/// pixel, row 0 (the top) first.
#[derive(Clone, Debug, PartialEq)]
pub struct ExtraChannel {
    pub name: String,
    pub values: Vec<f32>,
}

fn samples(values: impl Iterator<Item = f32>, half: bool) -> FlatSamples {
    if half {
        // Round to nearest: values beyond 65504 become inf, as half has no larger finite.
        FlatSamples::F16(values.map(f16::from_f32).collect())
    } else {
        FlatSamples::F32(values.collect())
    }
}

/// Encodes `film` (and `extra` channels, each with one value per pixel) as an EXR image
/// into `out`; `target` names the file in errors. Values are stored unchanged (NaN and
/// infinities included) in f32, or rounded to nearest in f16 when `half`.
pub fn encode(
    film: &Film,
    extra: &[ExtraChannel],
    half: bool,
    out: &mut BufWriter<File>,
    target: &Path,
) -> Result<()> {
    let err = |message: String| Error::Image {
        path: target.to_path_buf(),
        message,
    };
    if film.width == 0 || film.height == 0 {
        return Err(err(format!(
            "cannot write a {}x{} EXR",
            film.width, film.height
        )));
    }
    let n = film.pixels.len();
    let mut list: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
    for (name, axis) in [("R", 0), ("G", 1), ("B", 2)] {
        let values = film.pixels.iter().map(|p| p[axis]);
        list.push(AnyChannel::new(name, samples(values, half)));
    }
    for channel in extra {
        if channel.values.len() != n {
            return Err(err(format!(
                "channel {} has {} values for {n} pixels",
                channel.name,
                channel.values.len()
            )));
        }
        let values = channel.values.iter().copied();
        list.push(AnyChannel::new(
            channel.name.as_str(),
            samples(values, half),
        ));
    }
    let layer = Layer::new(
        (film.width as usize, film.height as usize),
        LayerAttributes::default(),
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(list),
    );
    Image::from_layer(layer)
        .write()
        .to_buffered(&mut *out)
        .map_err(|e| err(e.to_string()))
}

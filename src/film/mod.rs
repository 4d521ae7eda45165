//! Film: f32 accumulation, tone mapping, image output and error metrics; exact pixel
//! sums, partial images and their merge (distributed rendering).

mod color;
pub mod exact_sum;
pub mod exr;
mod linear_image;
pub mod merge;
mod output;
pub mod partial;
mod pixel_sums;
mod preflight;
pub mod tonemap;

pub use color::{Srgb8Table, linear_to_srgb, linear_to_srgb8, luminance, srgb_to_linear};
pub use linear_image::Film;
pub use output::{
    INTERRUPTED_EXIT_CODE, SUPPORTED_EXTENSIONS, check_image_path, install_interrupt_handler,
    write_atomic,
};
pub use pixel_sums::PixelSums;
pub use preflight::check_output_paths;
pub use tonemap::{Display8, ImageOptions, ToneMap};

//! Image textures: decoded images in linear float RGBA ([`Texture`]), wrap modes
//! ([`WrapMode`]), bilinear lookup ([`bilinear`]), a load-once cache keyed by canonical
//! path ([`TextureCache`]), procedural images made at load time ([`Procedural`]) and
//! the binding of a texture to a material slot ([`TextureRef`], [`MaterialTextures`]).

mod binding;
mod cache;
mod image;
mod procedural;
mod sample;
mod wrap;

pub use binding::{ALPHA_CUTOFF, MaterialTextures, TextureRef};
pub use cache::TextureCache;
pub use image::{Encoding, Texture};
pub use procedural::{Procedural, ProceduralKind};
pub use sample::bilinear;
pub use wrap::WrapMode;

//! Textures bound to a material: which map, how it wraps, how its coordinates scale.

use super::{Texture, WrapMode, bilinear};
use glam::{Vec2, Vec3};
use std::sync::Arc;

/// A cut-out map's coverage below this is a hole: rays pass through (the usual
/// alpha-test threshold; MTL `map_d`, glTF `alphaCutoff` default).
pub const ALPHA_CUTOFF: f32 = 0.5;

/// One texture as a material uses it: the shared image, its wrap mode, and the
/// transform of the surface's texture coordinates, `uv * scale + offset` (MTL `-s`
/// and `-o`, TOML `uv_scale`).
#[derive(Clone, Debug)]
pub struct TextureRef {
    pub texture: Arc<Texture>,
    pub wrap: WrapMode,
    pub scale: Vec2,
    pub offset: Vec2,
}

impl TextureRef {
    /// `texture` with repeat wrapping and no coordinate transform.
    pub fn new(texture: Arc<Texture>) -> Self {
        TextureRef {
            texture,
            wrap: WrapMode::Repeat,
            scale: Vec2::ONE,
            offset: Vec2::ZERO,
        }
    }

    /// The filtered colour (linear RGB) at surface coordinates `uv`.
    #[inline]
    pub fn rgb(&self, uv: Vec2) -> Vec3 {
        bilinear(&self.texture, uv * self.scale + self.offset, self.wrap).truncate()
    }

    /// The filtered coverage at `uv` ([`Texture::coverage_of`]; bilinear, then read).
    #[inline]
    pub fn coverage(&self, uv: Vec2) -> f32 {
        let t = bilinear(&self.texture, uv * self.scale + self.offset, self.wrap);
        self.texture.coverage_of(t)
    }
}

/// Two references are equal when they share the image (the same `Arc`, as the cache
/// hands out for one file) and its use.
impl PartialEq for TextureRef {
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.texture, &other.texture)
            && self.wrap == other.wrap
            && self.scale == other.scale
            && self.offset == other.offset
    }
}

/// The texture slots of a material. A colour map multiplies the material's colour
/// of the same lobe (the MTL rule: "`map_Kd` is multiplied by `Kd`").
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MaterialTextures {
    /// Multiplies `diffuse` (MTL `map_Kd`, TOML `texture`).
    pub diffuse: Option<TextureRef>,
    /// Multiplies `specular` (MTL `map_Ks`, TOML `specular_texture`).
    pub specular: Option<TextureRef>,
    /// Cut-out mask (MTL `map_d`, TOML `alpha_texture`): where its coverage is below
    /// [`ALPHA_CUTOFF`] the surface is not there for any ray.
    pub alpha: Option<TextureRef>,
}

impl MaterialTextures {
    pub fn is_empty(&self) -> bool {
        self.diffuse.is_none() && self.specular.is_none() && self.alpha.is_none()
    }

    /// Whether the surface is a hole at `uv` (a cut-out whose coverage is below
    /// [`ALPHA_CUTOFF`]). Always false without an alpha map.
    #[inline]
    pub fn is_hole(&self, uv: Vec2) -> bool {
        self.alpha
            .as_ref()
            .is_some_and(|a| a.coverage(uv) < ALPHA_CUTOFF)
    }
}

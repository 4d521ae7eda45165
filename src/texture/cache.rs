//! Load each texture file once per scene and share it.

use super::{Encoding, Texture};
use crate::error::Result;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Textures loaded so far, keyed by canonical path and [`Encoding`] (a file used both
/// as a colour map and as a cut-out mask is decoded once per use, since the two read
/// its channels differently). Every loader of one scene shares one cache, so an image
/// named by several materials, MTL files or meshes is decoded once and held once.
#[derive(Debug, Default)]
pub struct TextureCache {
    loaded: HashMap<(PathBuf, Encoding), Arc<Texture>>,
}

impl TextureCache {
    pub fn new() -> Self {
        Self::default()
    }

    /// The texture at `path`, decoding it on first use. The path must exist (the
    /// caller decides whether a missing file is an error or a warning); a file that
    /// does not decode is an error naming it.
    pub fn get(&mut self, path: &Path, encoding: Encoding) -> Result<Arc<Texture>> {
        let key = path
            .canonicalize()
            .map_err(|e| crate::error::Error::io(path, e))?;
        if let Some(t) = self.loaded.get(&(key.clone(), encoding)) {
            return Ok(t.clone());
        }
        let t = Arc::new(Texture::load(path, encoding)?);
        self.loaded.insert((key, encoding), t.clone());
        Ok(t)
    }

    /// Inserts a texture made in memory (a procedural one) under a key of its own.
    pub fn insert_generated(
        &mut self,
        key: String,
        make: impl FnOnce() -> Texture,
    ) -> Arc<Texture> {
        self.loaded
            .entry((
                PathBuf::from(format!("<generated>/{key}")),
                Encoding::Linear,
            ))
            .or_insert_with(|| Arc::new(make()))
            .clone()
    }

    /// How many distinct images are held.
    pub fn len(&self) -> usize {
        self.loaded.len()
    }

    pub fn is_empty(&self) -> bool {
        self.loaded.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_file_is_decoded_once_under_any_spelling_of_its_path() {
        let dir = std::env::temp_dir().join(format!("packet-render-cache-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("sub")).unwrap();
        let p = dir.join("a.png");
        image::RgbImage::from_pixel(2, 2, image::Rgb([9, 9, 9]))
            .save(&p)
            .unwrap();
        let mut c = TextureCache::new();
        let a = c.get(&p, Encoding::Srgb).unwrap();
        let b = c.get(&dir.join("sub/../a.png"), Encoding::Srgb).unwrap();
        assert!(Arc::ptr_eq(&a, &b));
        assert_eq!(c.len(), 1);
        let d = c.get(&p, Encoding::Linear).unwrap();
        assert!(!Arc::ptr_eq(&a, &d));
        assert_eq!(c.len(), 2);
    }
}

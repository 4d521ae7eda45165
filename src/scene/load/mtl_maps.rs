//! Texture map records of MTL files (`map_Kd`, `map_Ks`, `map_d`, ...): their options,
//! their files, and the warning or error each problem gets, located at the MTL line.
//!
//! tobj keeps a map record as the raw rest of the line (options included) and knows
//! no line numbers, so the MTL pre-scan collects the records here instead.

use crate::error::{Error, Result};
use crate::scene::Material;
use crate::texture::{Encoding, TextureCache, TextureRef, WrapMode};
use glam::Vec2;
use std::path::{Path, PathBuf};

/// Which material slot a map record fills.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MtlMapKind {
    /// `map_Kd`: multiplies `Kd`.
    Diffuse,
    /// `map_Ks`: multiplies `Ks`.
    Specular,
    /// `map_d`: cut-out mask.
    Alpha,
    /// A map this renderer does not use (`map_Bump`, `bump`, `norm`, `map_Ka`, `map_Ns`,
    /// `map_Ke`, `disp`, `decal`, `refl`): a warning, not silence.
    Unsupported,
}

impl MtlMapKind {
    pub fn from_key(key: &str) -> Option<MtlMapKind> {
        Some(match key {
            "map_Kd" => MtlMapKind::Diffuse,
            "map_Ks" => MtlMapKind::Specular,
            "map_d" => MtlMapKind::Alpha,
            "map_Bump" | "map_bump" | "bump" | "norm" | "map_Ka" | "map_Ns" | "map_Ke" | "disp"
            | "decal" | "refl" => MtlMapKind::Unsupported,
            _ => return None,
        })
    }
}

/// One map record: where it is, for which material, which file, with which options.
#[derive(Clone, Debug, PartialEq)]
pub struct MtlMap {
    pub mtl: PathBuf,
    pub line: usize,
    pub column: usize,
    pub key: String,
    pub kind: MtlMapKind,
    /// The `newmtl` it follows (`None` before the first).
    pub material: Option<String>,
    pub file: String,
    /// `-clamp on`.
    pub clamp: bool,
    /// `-s u v` and `-o u v` (the `w` component is ignored).
    pub scale: Vec2,
    pub offset: Vec2,
}

impl MtlMap {
    /// Parses `rest`, what follows the key on the line: options, then the file name
    /// (which may contain spaces). Malformed options are an error at the line.
    #[allow(clippy::too_many_arguments)]
    pub fn parse(
        mtl: &Path,
        line: usize,
        column: usize,
        key: &str,
        kind: MtlMapKind,
        material: Option<String>,
        rest: &str,
    ) -> Result<MtlMap> {
        let err = |msg: String| Error::input(mtl, line, column, msg);
        let mut map = MtlMap {
            mtl: mtl.to_path_buf(),
            line,
            column,
            key: key.to_string(),
            kind,
            material,
            file: String::new(),
            clamp: false,
            scale: Vec2::ONE,
            offset: Vec2::ZERO,
        };
        let mut s = rest.trim_start();
        while s.starts_with('-') {
            let (opt, after) = split_word(s);
            s = after;
            let numbers = |s: &mut &str, min: usize, max: usize| -> Result<Vec<f32>> {
                let mut v = Vec::new();
                while v.len() < max {
                    let (w, after) = split_word(s);
                    match w.parse::<f32>() {
                        Ok(x) if x.is_finite() => {
                            v.push(x);
                            *s = after;
                        }
                        _ => break,
                    }
                }
                if v.len() < min {
                    return Err(err(format!(
                        "map option `{opt}` needs {min} number(s) or more"
                    )));
                }
                Ok(v)
            };
            match opt {
                "-clamp" | "-blendu" | "-blendv" | "-cc" => {
                    let (w, after) = split_word(s);
                    if w != "on" && w != "off" {
                        return Err(err(format!(
                            "map option `{opt}` needs `on` or `off`, got `{w}`"
                        )));
                    }
                    if opt == "-clamp" {
                        map.clamp = w == "on";
                    }
                    s = after;
                }
                "-bm" | "-boost" | "-texres" => {
                    numbers(&mut s, 1, 1)?;
                }
                "-mm" => {
                    numbers(&mut s, 2, 2)?;
                }
                "-imfchan" | "-type" => {
                    let (w, after) = split_word(s);
                    if w.is_empty() {
                        return Err(err(format!("map option `{opt}` needs a value")));
                    }
                    s = after;
                }
                "-s" | "-o" | "-t" => {
                    let v = numbers(&mut s, 1, 3)?;
                    let uv = Vec2::new(
                        v[0],
                        v.get(1)
                            .copied()
                            .unwrap_or(if opt == "-s" { 1.0 } else { 0.0 }),
                    );
                    match opt {
                        "-s" => map.scale = uv,
                        "-o" => map.offset = uv,
                        _ => {} // turbulence: ignored
                    }
                }
                _ => return Err(err(format!("unknown map option `{opt}`"))),
            }
            s = s.trim_start();
        }
        let file = s.trim_end();
        if file.is_empty() {
            return Err(err(
                "expected a texture file name after the map options".into()
            ));
        }
        map.file = file.to_string();
        Ok(map)
    }

    /// The file the record names, relative to the MTL file's directory. Backslashes
    /// (Windows exporters: Crytek Sponza writes `textures\\x.tga`) are read as `/`
    /// when the name as written does not exist.
    pub fn resolve(&self) -> PathBuf {
        let dir = self.mtl.parent().unwrap_or(Path::new(""));
        let p = dir.join(&self.file);
        if p.is_file() || !self.file.contains('\\') {
            return p;
        }
        dir.join(self.file.replace('\\', "/"))
    }

    fn at(&self) -> String {
        format!("{}:{}", self.mtl.display(), self.line)
    }
}

fn split_word(s: &str) -> (&str, &str) {
    let s = s.trim_start();
    let end = s.find(char::is_whitespace).unwrap_or(s.len());
    (&s[..end], &s[end..])
}

/// Loads the textures the map records name and binds them to the materials of the
/// same name. A missing file is a warning at the MTL line (the material keeps its
/// plain colour); a file that does not decode is an error naming the file and the
/// MTL line; an unsupported map kind is a warning.
pub fn attach_maps(
    materials: &mut [Material],
    maps: &[MtlMap],
    cache: &mut TextureCache,
    warnings: &mut Vec<String>,
) -> Result<()> {
    for map in maps {
        let key = &map.key;
        if map.kind == MtlMapKind::Unsupported {
            warnings.push(format!(
                "{}: `{key}` maps are not supported; ignored",
                map.at()
            ));
            continue;
        }
        let Some(m) = map
            .material
            .as_ref()
            .and_then(|name| materials.iter_mut().rev().find(|m| &m.name == name))
        else {
            warnings.push(format!(
                "{}: `{key}` outside a material (no `newmtl` above); ignored",
                map.at()
            ));
            continue;
        };
        let path = map.resolve();
        if !path.is_file() {
            let colour = match map.kind {
                MtlMapKind::Diffuse => "its `Kd` colour",
                MtlMapKind::Specular => "its `Ks` colour",
                _ => "no cut-out",
            };
            warnings.push(format!(
                "{}: `{key}` texture `{}` not found (looked for {}); material `{}` renders with {colour}",
                map.at(),
                map.file,
                path.display(),
                m.name
            ));
            continue;
        }
        let encoding = if map.kind == MtlMapKind::Alpha {
            Encoding::Linear
        } else {
            Encoding::Srgb
        };
        let texture = cache.get(&path, encoding).map_err(|e| {
            Error::input(
                &map.mtl,
                map.line,
                map.column,
                format!("`{key}` texture: {e}"),
            )
        })?;
        let r = TextureRef {
            texture,
            wrap: if map.clamp {
                WrapMode::Clamp
            } else {
                WrapMode::Repeat
            },
            scale: map.scale,
            offset: map.offset,
        };
        match map.kind {
            MtlMapKind::Diffuse => m.textures.diffuse = Some(r),
            MtlMapKind::Specular => m.textures.specular = Some(r),
            MtlMapKind::Alpha => m.textures.alpha = Some(r),
            MtlMapKind::Unsupported => unreachable!("handled above"),
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(rest: &str) -> Result<MtlMap> {
        MtlMap::parse(
            Path::new("m.mtl"),
            7,
            1,
            "map_Kd",
            MtlMapKind::Diffuse,
            Some("a".into()),
            rest,
        )
    }

    #[test]
    fn options_and_file_names_with_spaces() {
        let m = parse("-s 2 3 1 -o 0.5 -clamp on -bm 1 my file.png").unwrap();
        assert_eq!(m.scale, Vec2::new(2.0, 3.0));
        assert_eq!(m.offset, Vec2::new(0.5, 0.0));
        assert!(m.clamp);
        assert_eq!(m.file, "my file.png");
        let m = parse("plain.tga").unwrap();
        assert_eq!((m.scale, m.offset, m.clamp), (Vec2::ONE, Vec2::ZERO, false));
    }

    #[test]
    fn malformed_options_are_located_errors() {
        for bad in ["-s", "-clamp maybe x.png", "-zz 1 x.png", "-s 1 2 3"] {
            let e = parse(bad).unwrap_err().to_string();
            assert!(e.starts_with("m.mtl:7:1:"), "{bad}: {e}");
        }
    }
}

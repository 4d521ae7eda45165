//! The `[environment]` table of a TOML scene (README.md, "Environment light"):
//!
//! ```toml
//! [environment]
//! color = [0.5, 0.6, 0.8]          # a constant sky, or
//! map = "sky.hdr"                  # an equirectangular .hdr / .exr file, or
//! map = { procedural = "sky", sun_direction = [1, 1, 0.5] }
//! scale = 1.0                      # multiplies the radiance
//! rotate_y = 90                    # degrees about the map's up axis
//! up = [0, 1, 0]                   # world direction of the map's zenith
//! ```
//!
//! Errors point at the offending value (file:line:column); a map file's own errors
//! (missing, unreadable, wrong format, bad texels) name the file and the `map` line.

use super::environment_map::read_environment_map;
use super::line_column;
use crate::error::{Error, Result};
use crate::scene::Environment;
use crate::scene::sky::{SkyParams, generate};
use glam::Vec3;
use serde::Deserialize;
use std::ops::Range;
use std::path::Path;
use toml::Spanned;

/// The `[environment]` table as written.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct EnvironmentDef {
    color: Option<Spanned<[f32; 3]>>,
    map: Option<Spanned<toml::Value>>,
    scale: Option<Spanned<f32>>,
    rotate_y: Option<Spanned<f32>>,
    up: Option<Spanned<[f32; 3]>>,
}

/// `map = { procedural = "sky", ... }`: [`SkyParams`] with defaults for what is left out.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SkyDef {
    procedural: String,
    width: Option<u32>,
    sun_direction: Option<[f32; 3]>,
    sun_angle: Option<f32>,
    sun_radiance: Option<[f32; 3]>,
    zenith: Option<[f32; 3]>,
    horizon: Option<[f32; 3]>,
    ground: Option<[f32; 3]>,
}

/// Largest procedural map width.
const MAX_SKY_WIDTH: u32 = 8192;

/// Builds the environment of `def` (the table spanning `table` in `text`); `path` is the
/// scene file, which relative map paths are resolved against.
pub(super) fn environment(
    def: &EnvironmentDef,
    table: Range<usize>,
    path: &Path,
    text: &str,
) -> Result<Environment> {
    let at = |span: Range<usize>, m: String| {
        let (line, column) = line_column(text, span.start);
        Error::input(path, line, column, m)
    };
    // A parameter error from `Environment` located at a value.
    let located = |span: Range<usize>| {
        move |e: Error| match e {
            Error::Parameter { message, .. } => at(span.clone(), message),
            other => other,
        }
    };
    let env = match (&def.color, &def.map) {
        (Some(_), Some(m)) => {
            return Err(at(
                m.span(),
                "give either `color` (a constant sky) or `map`, not both".into(),
            ));
        }
        (None, None) => {
            return Err(at(
                table,
                "`[environment]` needs `color = [r, g, b]` or `map = \"file.hdr|.exr\"` or `map = { procedural = \"sky\" }`".into(),
            ));
        }
        (Some(c), None) => {
            Environment::constant(Vec3::from_array(*c.get_ref())).map_err(located(c.span()))?
        }
        (None, Some(m)) => map(m, path, &at).map_err(located(m.span()))?,
    };
    let env = match &def.scale {
        Some(s) => env.with_scale(*s.get_ref()).map_err(located(s.span()))?,
        None => env,
    };
    let up = def
        .up
        .as_ref()
        .map_or(Vec3::Y, |u| Vec3::from_array(*u.get_ref()));
    let rotate = def.rotate_y.as_ref().map_or(0.0, |r| *r.get_ref());
    let span = def
        .up
        .as_ref()
        .map(|u| u.span())
        .or(def.rotate_y.as_ref().map(|r| r.span()))
        .unwrap_or(0..0);
    env.with_frame(up, rotate).map_err(located(span))
}

fn map(
    m: &Spanned<toml::Value>,
    path: &Path,
    at: &impl Fn(Range<usize>, String) -> Error,
) -> Result<Environment> {
    match m.get_ref() {
        toml::Value::String(file) => {
            let resolved = path.parent().unwrap_or(Path::new("")).join(file);
            if !resolved.is_file() {
                return Err(at(
                    m.span(),
                    format!(
                        "environment map `{file}` not found (resolved to {})",
                        resolved.display()
                    ),
                ));
            }
            let (w, h, texels) = read_environment_map(&resolved)
                .map_err(|e| at(m.span(), format!("environment map `{file}`: {e}")))?;
            Environment::map(w, h, texels, &resolved.display().to_string())
                .map_err(|e| at(m.span(), e.to_string()))
        }
        toml::Value::Table(_) => {
            let def: SkyDef = m
                .get_ref()
                .clone()
                .try_into()
                .map_err(|e: toml::de::Error| {
                    at(
                        m.span(),
                        format!("procedural map: {}", e.message().trim_end()),
                    )
                })?;
            if def.procedural != "sky" {
                return Err(at(
                    m.span(),
                    format!(
                        "unknown procedural map `{}`: the one procedural map is `sky`",
                        def.procedural
                    ),
                ));
            }
            let p =
                sky_params(&def).map_err(|msg| at(m.span(), format!("procedural sky: {msg}")))?;
            let (w, h, texels) = generate(&p);
            Environment::map(w, h, texels, "procedural sky")
        }
        _ => Err(at(
            m.span(),
            "`map` must be a file name (string) or a table `{ procedural = \"sky\", ... }`".into(),
        )),
    }
}

fn sky_params(d: &SkyDef) -> std::result::Result<SkyParams, String> {
    let mut p = SkyParams::default();
    if let Some(w) = d.width {
        if !(2..=MAX_SKY_WIDTH).contains(&w) {
            return Err(format!(
                "`width` must be between 2 and {MAX_SKY_WIDTH}, got {w}"
            ));
        }
        p.width = w as usize;
    }
    if let Some(s) = d.sun_direction {
        let s = Vec3::from_array(s);
        if !(s.is_finite() && s.length_squared() > 1e-20) {
            return Err(format!(
                "`sun_direction` must be a finite non-zero vector, got {s}"
            ));
        }
        p.sun_direction = s.normalize();
    }
    if let Some(a) = d.sun_angle {
        if !(a.is_finite() && a > 0.0 && a < 180.0) {
            return Err(format!(
                "`sun_angle` must be between 0 and 180 degrees, got {a}"
            ));
        }
        p.sun_angle_deg = a;
    }
    for (value, name, slot) in [
        (d.sun_radiance, "sun_radiance", &mut p.sun_radiance),
        (d.zenith, "zenith", &mut p.zenith),
        (d.horizon, "horizon", &mut p.horizon),
        (d.ground, "ground", &mut p.ground),
    ] {
        if let Some(c) = value {
            let c = Vec3::from_array(c);
            if !(c.is_finite() && c.min_element() >= 0.0) {
                return Err(format!("`{name}` must be finite and non-negative, got {c}"));
            }
            *slot = c;
        }
    }
    Ok(p)
}

//! Named meshes (objects) and `[[instance]]` entries of TOML scenes.
//!
//! ```toml
//! [[mesh]]
//! name = "bunny"            # an object; drawn where it stands unless instance_only
//! file = "bunny.obj"
//! instance_only = true
//!
//! [[instance]]
//! object = "bunny"
//! translate = [1, 0, 0]     # or rotate / rotate_y / scale, or matrix = 3 or 4 rows of 4
//! material = "red"          # optional: overrides the object's materials
//! ```
//!
//! The object's own `translate`/`rotate`/`scale` are baked into its object space; an
//! instance's transform is applied on top. Objects are stored once and share one
//! bottom-level structure ([`crate::accel::InstanceAccel`]).

use super::toml_scene::{Builder, MeshDef, Placement, V3, mesh_transform};
use crate::error::Result;
use glam::{Mat4, Vec4};
use serde::Deserialize;
use std::collections::BTreeMap;
use toml::Spanned;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct InstanceDef {
    object: Spanned<String>,
    translate: Option<V3>,
    scale: Option<Spanned<toml::Value>>,
    rotate_y: Option<Spanned<f32>>,
    rotate: Option<V3>,
    /// Row-major affine matrix: 3 rows of 4, or 4 rows with last row `0 0 0 1`.
    matrix: Option<Spanned<Vec<Vec<f32>>>>,
    material: Option<Spanned<String>>,
}

/// The named meshes read so far.
#[derive(Default)]
pub(super) struct Objects {
    ids: BTreeMap<String, u32>,
}

impl Objects {
    /// Loads a named `[[mesh]]` as an object (in its own space, with its own transform
    /// baked in) and, unless `instance_only`, places it once with the identity.
    pub(super) fn mesh(&mut self, b: &mut Builder, def: &MeshDef) -> Result<()> {
        let cx = b.cx;
        let name = def.name.as_ref().expect("named mesh");
        if self.ids.contains_key(name.get_ref()) {
            return Err(cx.at(
                name,
                format!("object `{}` is defined twice", name.get_ref()),
            ));
        }
        if let Some(v) = &def.velocity {
            return Err(cx.at(
                v,
                "a named mesh (an instanced object) cannot move: drop `velocity` or `name`",
            ));
        }
        // Load into an empty mesh (materials go to the scene as usual), then move those
        // triangles to the object.
        let saved = std::mem::take(&mut b.b.mesh);
        let loaded = b.mesh(def);
        let object = std::mem::replace(&mut b.b.mesh, saved);
        loaded?;
        let id = b.b.instances.add_object(name.get_ref(), object);
        self.ids.insert(name.get_ref().clone(), id);
        let only = def.instance_only.as_ref().is_some_and(|v| *v.get_ref());
        if !only {
            b.b.instances
                .add_instance(id, Mat4::IDENTITY, None)
                .map_err(|e| cx.at(name, e))?;
        }
        Ok(())
    }

    /// Places an object; an unknown object name is an error at the name.
    pub(super) fn instance(&self, b: &mut Builder, def: &InstanceDef) -> Result<()> {
        let cx = b.cx;
        let Some(&id) = self.ids.get(def.object.get_ref()) else {
            let known = if self.ids.is_empty() {
                "no objects are defined (give a [[mesh]] a `name`)".to_string()
            } else {
                format!(
                    "defined objects: {}",
                    self.ids.keys().cloned().collect::<Vec<_>>().join(", ")
                )
            };
            return Err(cx.at(
                &def.object,
                format!("unknown object `{}`; {known}", def.object.get_ref()),
            ));
        };
        let placement = Placement {
            translate: &def.translate,
            scale: &def.scale,
            rotate_y: &def.rotate_y,
            rotate: &def.rotate,
        };
        let to_world = match &def.matrix {
            None => mesh_transform(cx, &placement)?,
            Some(m) => {
                if def.translate.is_some()
                    || def.scale.is_some()
                    || def.rotate.is_some()
                    || def.rotate_y.is_some()
                {
                    return Err(cx.at(
                        m,
                        "give either `matrix` or translate/rotate/scale, not both",
                    ));
                }
                matrix(m).map_err(|e| cx.at(m, e))?
            }
        };
        let material = def
            .material
            .as_ref()
            .map(|_| b.material(&def.material))
            .transpose()?;
        let anchor = def.matrix.as_ref().map_or(def.object.span(), |m| m.span());
        b.b.instances
            .add_instance(id, to_world, material)
            .map_err(|e| {
                cx.error(
                    &anchor,
                    format!("instance of `{}`: {e}", def.object.get_ref()),
                )
            })?;
        Ok(())
    }
}

/// A row-major 3x4 or 4x4 (affine) matrix as a glam matrix.
fn matrix(m: &Spanned<Vec<Vec<f32>>>) -> std::result::Result<Mat4, String> {
    let rows = m.get_ref();
    let shape = "`matrix` must be 3 or 4 rows of 4 finite numbers (row-major, affine)";
    if !(rows.len() == 3 || rows.len() == 4) || rows.iter().any(|r| r.len() != 4) {
        return Err(shape.into());
    }
    if rows.iter().flatten().any(|x| !x.is_finite()) {
        return Err(shape.into());
    }
    if rows.len() == 4 && rows[3] != [0.0, 0.0, 0.0, 1.0] {
        return Err("the last row of `matrix` must be [0, 0, 0, 1] (affine maps only)".into());
    }
    let r = |i: usize| Vec4::new(rows[i][0], rows[i][1], rows[i][2], rows[i][3]);
    Ok(Mat4::from_cols(r(0), r(1), r(2), Vec4::W).transpose())
}

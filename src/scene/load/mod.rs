//! Scene loading: TOML scene files (format documented in `scenes/README.md`) and
//! OBJ/MTL meshes. Every error names the file, the line and what was expected; every
//! scene goes through [`SceneBuilder::finish`](crate::scene::SceneBuilder::finish) last.

mod entry;
mod environment_map;
mod mtl_maps;
mod obj;
mod ply;
mod toml_environment;
mod toml_instance;
mod toml_scene;

pub use entry::{add_obj_mesh, load_mesh, load_mesh_with, load_obj_scene, load_scene};
pub(crate) use entry::{line_column, print_warnings};
pub use environment_map::read_environment_map;
pub use obj::{
    ObjMesh, load_obj, load_obj_from_bytes, load_obj_from_bytes_with, load_obj_with,
    material_from_mtl,
};
pub use ply::{PlyMesh, load_ply, load_ply_from_bytes};
pub use toml_scene::{load_toml_scene, parse_toml_scene};

//! Scene loading: TOML scene files and OBJ/MTL meshes.

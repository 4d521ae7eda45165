//! Any bytes as an OBJ file (pre-scan, then tobj): an error or a mesh, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    // `mtllib` names resolve beside this (nonexistent) file: a missing-MTL warning.
    let _ = packet_render::scene::load::load_obj_from_bytes(data, Path::new("/nonexistent/fuzz.obj"));
});

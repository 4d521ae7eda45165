//! Any bytes fed to the TOML scene parser: an error or a scene, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        // Mesh paths resolve beside this (nonexistent) file: a missing-file error.
        let _ = packet_render::scene::load::parse_toml_scene(text, Path::new("/nonexistent/fuzz.toml"));
    }
});

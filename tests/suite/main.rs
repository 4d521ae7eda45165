//! The integration tests, one binary: each file of `tests/suite/` is a module here, so the
//! library's generic code is instantiated and linked once rather than once per file (22
//! separate binaries made the CI build twice as long). `accel_equivalence` and
//! `simd_equivalence` stay binaries of their own: CI builds them again without the host
//! CPU's features (`.ci/run`). Select a file's tests by its module path, e.g.
//! `cargo test --test suite wavefront::`.

#[path = "../common/mod.rs"]
mod common;
#[path = "../robust/mod.rs"]
mod robust;

mod adaptive;
mod bad_input;
mod cli;
mod cli_output;
mod distributed;
mod distribution;
mod environment;
mod hostile_scenes;
mod images;
mod instancing;
mod load;
mod properties;
mod queries;
mod robustness_precision;
mod robustness_rays;
mod robustness_watertight;
mod scenes;
mod stream_batches;
mod textures;
mod transmitted_shadows;
mod wavefront;

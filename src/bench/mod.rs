//! The throughput protocol of `shared/BENCHMARK.md`, shared by `packet-render bench` and
//! the criterion benches: one fixed set of primary, shadow and diffuse rays over a
//! mesh, timed per tracing mode, with the checksums other tracers must reproduce.
//!
//! Reading of the protocol, matching `shared/anchors/embree/src/protocol.h`: framing
//! and camera basis in f64 rounded to f32, ray directions normalised in f32 as
//! `v * (1/|v|)`; shadow and diffuse rays start from the primary hits of the mode under
//! test's own structure, computed once untimed; rays are generated and traced in 8x8
//! tiles (ordered as 4x4 blocks, so 16 consecutive rays are a 4x4 pixel block and 8 a
//! 4x2 block), and bands of 8 rows are handed to threads dynamically. Stream modes
//! (`bvh4-stream`, `bvh8-stream`) get a band's valid rays, in that tile order, as one
//! batch (Embree's harness hands `rtcIntersect1M` one tile of 64 rays).

pub mod compare;
pub mod converge;
pub mod cpu_time;
pub mod lecture;
mod modes;
pub mod precision;
mod protocol;
mod run;
pub mod sweep;
mod table;
mod timing;
mod workload;

pub use crate::simd::instruction_set;
pub use modes::*;
pub use protocol::*;
pub use run::*;
pub use table::*;
pub use timing::*;
pub use workload::*;

//! The only module that names `wide` types. Everything else asks for lanes through
//! [`Lanes`]: [`F4`] for the four children of a BVH4 node or the four triangles of a
//! leaf group, and [`Packet`] for a coherent ray packet of [`PACKET_WIDTH`] rays.
//!
//! Lane width: with AVX-512 (`target-cpu=native` on the development machines) a
//! 16-wide packet is one register; without it `wide` emulates 16 lanes with two 8-lane
//! (AVX2) or four 4-lane (SSE2) registers, which stays correct, only slower.
//!
//! Masks are lane vectors whose lanes are all-ones or all-zeros, as `wide` returns
//! from comparisons; [`Lanes::bitmask`] turns one into an integer with bit `i` for lane `i`.

pub mod aperture;
pub mod bin_box;
pub mod bin_index;
pub mod box_areas;
pub mod camera;
pub mod compact;
pub mod direct_light;
pub mod exact_sums;
pub mod glass_shadow;
pub mod jittered;
pub mod jittered_pack;
pub mod kernels;
pub mod lane_ranges;
pub mod lane_rays;
mod lanes;
pub mod lanes3;
pub mod left_pack;
pub mod pow;
pub mod prefetch;
pub mod quad_samples;
pub mod quant;
pub mod ray_gather;
pub mod ray_store;
pub mod round_light;
pub mod shadow_cull;
pub mod slab_fma;
pub mod specular;
pub mod sphere_clearance;
pub mod splitmix;
pub mod surface;
pub mod tiny;
pub mod trig;

pub use lanes::{F4, F8, F16, Lanes, PACKET_WIDTH, Packet, instruction_set};

//! Scalar geometry: rays, bounds, and the intersection maths every accelerator and
//! every SIMD kernel is checked against. One place for the maths.

mod aabb;
mod offset;
mod ray;
mod sphere;
pub mod terminator;
mod triangle;

pub use aabb::{Aabb, ROBUST_FAR_SCALE};
pub use offset::{offset_ray_origin, offset_ray_origin_scaled, orthonormal_basis};
pub use ray::{LaneRays, Ray, RayPacket, RayQuery};
pub use sphere::intersect_sphere;
pub use triangle::{PrimHit, intersect_triangle, intersect_triangle_f64};

/// A closest hit inside one primitive set: distance, primitive index and the
/// barycentric coordinates of the hit (`u`, `v` weight the second and third vertex;
/// for spheres they are unused and zero).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    pub prim: u32,
    pub u: f32,
    pub v: f32,
}

//! Scalar geometry: rays, bounds, and the intersection maths every accelerator and
//! every SIMD kernel is checked against. One place for the maths.

mod aabb;
mod offset;
pub mod piecewise;
mod plane;
mod ray;
mod sphere;
pub mod terminator;
mod triangle;
pub mod warp;

pub use aabb::{Aabb, ROBUST_FAR_SCALE};
pub use offset::{
    OffsetOrigins, SPAWN_TO_ERROR, offset_ray_origin, orthonormal_basis, spawn_ray_to,
};
pub use plane::{intersect_plane, plane_point};
pub use ray::{LaneRays, Ray, RayPacket, RayQuery, dominant_axis, octant};
pub use sphere::{intersect_sphere, sphere_point};
pub(crate) use triangle::err as triangle_err;
pub use triangle::{PrimHit, gamma, intersect_triangle, intersect_triangle_f64, triangle_point};

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

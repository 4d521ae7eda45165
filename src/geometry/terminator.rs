//! The shadow-ray origin on a triangle with vertex normals, after Hanika, "Hacking the
//! Shadow Terminator" (Ray Tracing Gems II, ch. 4, 2021).
//!
//! A coarse mesh with interpolated normals is shaded as if it were smooth, but its
//! shadow rays leave the flat triangles. Near the terminator the light is above the
//! shading normal's horizon yet below the neighbouring facets, so those rays hit the
//! mesh itself: hard, faceted shadows on the lit side ("the shadow terminator
//! problem"). Hanika's fix moves the shadow-ray origin onto a smooth surface
//! approximated from the vertex normals: the hit point is projected onto the tangent
//! plane of each vertex (only where it lies *below* that plane), and the three
//! projections are interpolated with the hit's barycentrics, giving a quadratic patch
//! through the vertices that bulges out like the surface the normals describe.

use glam::Vec3;

/// Shadow-ray base point for the hit `p` with barycentrics `bary` (weights of the
/// corners `corners`) on a triangle whose unit vertex normals are `normals`, all
/// oriented to the side being shaded. Returns `p` itself when the projected point
/// would not lie on that side of the flat triangle (normals bent inwards, a degenerate
/// triangle) or is not finite, so it never moves an origin into the surface.
///
/// `n_geometric` is the unit geometric normal on the shaded side.
pub fn shadow_terminator_point(
    p: Vec3,
    corners: [Vec3; 3],
    normals: [Vec3; 3],
    bary: [f32; 3],
    n_geometric: Vec3,
) -> Vec3 {
    // RTG II ch. 4: the projection of p onto the tangent plane of vertex i is
    // p - ((p - p_i)·n_i) n_i, applied only below the plane (min(0, ·)), and the result
    // is Σ bary_i proj_i. As Σ bary_i = 1, that is p plus the weighted lifts, which
    // avoids re-adding Σ bary_i (p - p_i) = 0 with its rounding.
    let mut lift = Vec3::ZERO;
    for i in 0..3 {
        let depth = (p - corners[i]).dot(normals[i]).min(0.0);
        lift -= (bary[i] * depth) * normals[i];
    }
    let q = p + lift;
    if q.is_finite() && (q - p).dot(n_geometric) > 0.0 {
        q
    } else {
        p
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat triangle whose normals all equal the face normal: nothing moves.
    #[test]
    fn flat_normals_leave_the_point_alone() {
        let c = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let n = [Vec3::Z; 3];
        let p = Vec3::new(0.25, 0.25, 0.0);
        assert_eq!(
            shadow_terminator_point(p, c, n, [0.5, 0.25, 0.25], Vec3::Z),
            p
        );
    }

    /// Corners on the unit sphere with their radial normals: the shifted point lies
    /// above the flat triangle and closer to the sphere than the hit point, inside
    /// the tangent planes' envelope (never past the sphere's radius by more than the
    /// curvature of a quadratic patch allows).
    #[test]
    fn sphere_normals_lift_the_point_towards_the_sphere() {
        let c = [
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
        ];
        let ng = Vec3::ONE.normalize();
        let bary = [1.0 / 3.0; 3];
        let p = (c[0] + c[1] + c[2]) / 3.0;
        let q = shadow_terminator_point(p, c, c, bary, ng);
        // The centroid is at distance 1/√3 ≈ 0.577 from the centre; each tangent
        // plane x_i = 1 lifts it along its normal by 2/3, so q = p + (2/9)(1,1,1):
        // distance 0.577 + 0.385 = 0.962, between the flat face and the sphere.
        let expect = p + Vec3::splat(2.0 / 9.0);
        assert!((q - expect).length() < 1e-6, "{q} vs {expect}");
        assert!(q.length() < 1.0 && q.length() > p.length());
    }

    /// Normals bent inwards (a concave vertex ring) would push the origin below the
    /// face: the hit point is kept.
    #[test]
    fn inward_normals_never_move_the_origin_inside() {
        let c = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let n = [
            Vec3::new(-0.5, -0.5, 0.7).normalize(),
            Vec3::new(0.7, 0.0, 0.7).normalize(),
            Vec3::new(0.0, 0.7, 0.7).normalize(),
        ];
        let p = Vec3::new(0.3, 0.3, 0.0);
        let q = shadow_terminator_point(p, c, n, [0.4, 0.3, 0.3], Vec3::Z);
        assert!((q - p).dot(Vec3::Z) >= 0.0);
    }
}

use glam::Vec3;

/// Axis-aligned bounding box. The empty box has `min = +inf`, `max = -inf` so that
/// growing it by any point or box gives that point or box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

impl Default for Aabb {
    fn default() -> Self {
        Self::EMPTY
    }
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    pub fn new(min: Vec3, max: Vec3) -> Self {
        Aabb { min, max }
    }

    pub fn from_point(p: Vec3) -> Self {
        Aabb { min: p, max: p }
    }

    pub fn grow(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    pub fn union(&self, o: &Aabb) -> Aabb {
        Aabb {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x || self.min.y > self.max.y || self.min.z > self.max.z
    }

    pub fn center(&self) -> Vec3 {
        0.5 * (self.min + self.max)
    }

    pub fn extent(&self) -> Vec3 {
        if self.is_empty() {
            Vec3::ZERO
        } else {
            self.max - self.min
        }
    }

    pub fn diagonal(&self) -> f32 {
        self.extent().length()
    }

    /// Surface area, 0 for an empty box (the SAH's measure).
    pub fn area(&self) -> f32 {
        let e = self.extent();
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }

    pub fn largest_axis(&self) -> usize {
        let e = self.extent();
        if e.x >= e.y && e.x >= e.z {
            0
        } else if e.y >= e.z {
            1
        } else {
            2
        }
    }

    /// Slab test (Kay-Kajiya). Returns the entry distance if the box overlaps
    /// `[tmin, tmax]`.
    ///
    /// The near and far planes are chosen by the sign of each `inv_dir` component
    /// rather than by `min`/`max` of the two distances, so an empty box (min > max) is
    /// never hit, and `-0.0` selects the planes of a negative direction, as its
    /// infinite reciprocal requires. Numeric traps handled: a zero direction component
    /// gives `inv_dir = ±inf` and the slab interval is the whole line or empty; if the
    /// origin lies exactly on a plane the product is `0 * inf = NaN`, and `f32::max`/
    /// `min` return the non-NaN operand, so that bound is ignored: the ray lies in the
    /// plane and is treated as inside the slab (conservative, never a false miss). The
    /// far distance is scaled by `1 + 2 gamma(3)` (Ize 2013, "Robust BVH Ray
    /// Traversal") so that rounding never culls a box the ray touches.
    #[inline]
    pub fn intersect(&self, origin: Vec3, inv_dir: Vec3, tmin: f32, tmax: f32) -> Option<f32> {
        let mut enter = tmin;
        // The current closest hit is scaled like the far planes: an entry distance that
        // rounds above a hit it actually precedes must not cull the box (it would hide a
        // hit one ulp nearer, on the neighbour across a shared edge).
        let mut exit = tmax * ROBUST_FAR_SCALE;
        for a in 0..3 {
            let (near, far) = if inv_dir[a].is_sign_negative() {
                (self.max[a], self.min[a])
            } else {
                (self.min[a], self.max[a])
            };
            enter = enter.max((near - origin[a]) * inv_dir[a]);
            exit = exit.min((far - origin[a]) * inv_dir[a] * ROBUST_FAR_SCALE);
        }
        if enter <= exit { Some(enter) } else { None }
    }
}

/// `1 + 2 * gamma(3)` with `gamma(n) = n eps / (1 - n eps)`, eps = 2^-24 (pbrt-v3 §3.9.2).
pub const ROBUST_FAR_SCALE: f32 =
    1.0 + 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5);

#[cfg(test)]
mod tests {
    use super::*;

    fn unit() -> Aabb {
        Aabb::new(Vec3::ZERO, Vec3::ONE)
    }

    #[test]
    fn hit_and_miss() {
        let b = unit();
        let o = Vec3::new(0.5, 0.5, -1.0);
        let d = Vec3::new(0.0, 0.0, 1.0);
        assert_eq!(b.intersect(o, Vec3::ONE / d, 0.0, f32::INFINITY), Some(1.0));
        let o2 = Vec3::new(1.5, 0.5, -1.0);
        assert_eq!(b.intersect(o2, Vec3::ONE / d, 0.0, f32::INFINITY), None);
        // interval ends before the box
        assert_eq!(b.intersect(o, Vec3::ONE / d, 0.0, 0.5), None);
    }

    #[test]
    fn signed_zero_directions() {
        let b = unit();
        for dz in [0.0f32, -0.0] {
            let d = Vec3::new(1.0, 0.0, dz);
            let inv = Vec3::ONE / d;
            // inside the slabs of y and z: hit
            assert!(
                b.intersect(Vec3::new(-1.0, 0.5, 0.5), inv, 0.0, f32::INFINITY)
                    .is_some()
            );
            // outside the z slab: miss whatever the sign of zero
            assert!(
                b.intersect(Vec3::new(-1.0, 0.5, 1.5), inv, 0.0, f32::INFINITY)
                    .is_none()
            );
            // origin exactly on the z = 1 plane: conservative hit
            assert!(
                b.intersect(Vec3::new(-1.0, 0.5, 1.0), inv, 0.0, f32::INFINITY)
                    .is_some()
            );
        }
    }

    #[test]
    fn empty_box_never_hit() {
        let d = Vec3::new(1.0, 1.0, 1.0).normalize();
        assert!(
            Aabb::EMPTY
                .intersect(Vec3::ZERO, Vec3::ONE / d, 0.0, f32::INFINITY)
                .is_none()
        );
        assert_eq!(Aabb::EMPTY.area(), 0.0);
    }
}

//! Ray sorting before stream traversal: the valid rays of a batch ordered by direction
//! octant, then by the Morton code of their origin in the batch's origin box (10 bits
//! per axis), as the ray-sorting schemes of Garanzha and Loop ("Fast Ray Sorting and
//! Breadth-First Packet Traversal for GPU Ray Tracing", Eurographics 2010: hashed
//! origin and direction keys) and Moon et al. ("Cache-Oblivious Ray Reordering", ACM
//! TOG 29(3), 2010: Morton order of hit points) order rays so that a run of them reads
//! the same part of the tree.
//!
//! The stream kernel (`stream.rs`) bins by octant anyway; this order only changes the
//! order of a bin's rays, so every node's list holds the same rays as without it (which
//! rays enter a node does not depend on their order) and the answers are the same. What
//! it can change is how the lists' rays lie in the ray records (neighbouring origins in
//! neighbouring records). A least-significant-digit radix sort: three passes of 11 bits
//! over the 33-bit keys, each key packed above its ray's index in one `u64`.

use crate::geometry::{Ray, octant};

/// Bits of the Morton code per axis.
const AXIS_BITS: u32 = 10;
/// Key bits: the octant (3) above the Morton code (3 x 10).
const KEY_BITS: u32 = 3 + 3 * AXIS_BITS;
/// Bits of the ray index below the key.
const INDEX_BITS: u32 = 64 - KEY_BITS;
/// Bits per radix pass.
const DIGIT_BITS: u32 = 11;
const _: () = assert!(KEY_BITS.div_ceil(DIGIT_BITS) * DIGIT_BITS == KEY_BITS);

/// `x` (below 2^10) with two zero bits after each of its bits.
fn spread3(x: u32) -> u64 {
    let mut x = x as u64 & 0x3ff;
    x = (x | x << 16) & 0x0300_00ff;
    x = (x | x << 8) & 0x0300_f00f;
    x = (x | x << 4) & 0x030c_30c3;
    (x | x << 2) & 0x0924_9249
}

/// The Morton code of cell `c` (each below 2^10): x in the lowest bit of each triple.
pub(super) fn morton3(c: [u32; 3]) -> u64 {
    spread3(c[0]) | spread3(c[1]) << 1 | spread3(c[2]) << 2
}

/// Reusable buffers of the sort.
#[derive(Default)]
pub(super) struct RaySort {
    keys: Vec<u64>,
    tmp: Vec<u64>,
}

impl RaySort {
    /// Writes to `order` the indices of the valid rays of `rays` (`Ray::is_valid`) in
    /// key order (octant, then origin Morton code; ties in the caller's order) and
    /// returns the first position of each octant in it (and the end).
    ///
    /// Panics if `rays` has 2^31 rays or more (the index bits).
    pub(super) fn sort(&mut self, rays: &[Ray], order: &mut Vec<u32>) -> [u32; 9] {
        assert!(
            (rays.len() as u64) < 1 << INDEX_BITS,
            "ray index exceeds the sort key"
        );
        let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        for r in rays.iter().filter(|r| r.is_valid()) {
            for a in 0..3 {
                lo[a] = lo[a].min(r.origin[a]);
                hi[a] = hi[a].max(r.origin[a]);
            }
        }
        let cells = (1u32 << AXIS_BITS) as f32;
        // Origins are finite for valid rays; a flat or empty box gives cell 0.
        let scale = [0, 1, 2].map(|a| {
            let ext = hi[a] - lo[a];
            if ext > 0.0 && ext.is_finite() {
                cells / ext
            } else {
                0.0
            }
        });
        self.keys.clear();
        let mut starts = [0u32; 9];
        for (i, r) in rays.iter().enumerate() {
            if !r.is_valid() {
                continue;
            }
            let o = octant(r.dir);
            starts[o + 1] += 1;
            // `as u32` saturates (NaN to 0), `min` keeps the top edge in the last cell.
            let c = [0, 1, 2]
                .map(|a| (((r.origin[a] - lo[a]) * scale[a]) as u32).min((1 << AXIS_BITS) - 1));
            let key = (o as u64) << (3 * AXIS_BITS) | morton3(c);
            self.keys.push(key << INDEX_BITS | i as u64);
        }
        for o in 0..8 {
            starts[o + 1] += starts[o];
        }
        self.radix();
        order.clear();
        order.extend(
            self.keys
                .iter()
                .map(|&k| (k & ((1 << INDEX_BITS) - 1)) as u32),
        );
        starts
    }

    /// Sorts `keys` by their top `KEY_BITS` bits, stably.
    fn radix(&mut self) {
        let n = self.keys.len();
        self.tmp.clear();
        self.tmp.resize(n, 0);
        let mut shift = INDEX_BITS;
        while shift < 64 {
            let digit = |k: u64| (k >> shift) as usize & ((1 << DIGIT_BITS) - 1);
            let mut count = vec![0u32; 1 << DIGIT_BITS];
            for &k in &self.keys {
                count[digit(k)] += 1;
            }
            let mut sum = 0;
            for c in &mut count {
                (*c, sum) = (sum, sum + *c);
            }
            for &k in &self.keys {
                let d = digit(k);
                self.tmp[count[d] as usize] = k;
                count[d] += 1;
            }
            std::mem::swap(&mut self.keys, &mut self.tmp);
            shift += DIGIT_BITS;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn morton_interleaves_x_lowest() {
        assert_eq!(morton3([1, 0, 0]), 1);
        assert_eq!(morton3([0, 1, 0]), 2);
        assert_eq!(morton3([0, 0, 1]), 4);
        assert_eq!(morton3([3, 0, 0]), 0b1001);
        assert_eq!(morton3([1023, 1023, 1023]), (1 << 30) - 1);
        assert_eq!(morton3([0, 0, 512]), 1 << 29);
    }

    /// The order is a permutation of the valid rays, grouped by octant at the returned
    /// starts, and within an octant the origins' Morton codes never decrease (checked
    /// against the codes computed again from the origins).
    #[test]
    fn sorted_rays_are_the_valid_ones_by_octant_then_origin() {
        let mut next = crate::test_rng::xorshift64(0x9e37_79b9_7f4a_7c15);
        let mut rays = Vec::new();
        for i in 0..5000 {
            let mut u = || (next() >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0;
            let mut r = Ray::new(Vec3::new(u(), u(), u()) * 7.0, Vec3::new(u(), u(), u()));
            if i % 17 == 0 {
                r.dir = Vec3::ZERO;
            }
            rays.push(r);
        }
        let mut order = Vec::new();
        let starts = RaySort::default().sort(&rays, &mut order);
        let valid: Vec<u32> = (0..rays.len() as u32)
            .filter(|&i| rays[i as usize].is_valid())
            .collect();
        let mut seen = order.clone();
        seen.sort_unstable();
        assert_eq!(seen, valid);
        assert_eq!(starts[8] as usize, order.len());
        let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        for &i in &valid {
            lo = lo.min(rays[i as usize].origin);
            hi = hi.max(rays[i as usize].origin);
        }
        let code = |o: Vec3| {
            let c = ((o - lo) * (Vec3::splat(1024.0) / (hi - lo))).to_array();
            morton3(c.map(|x| (x as u32).min(1023)))
        };
        for o in 0..8 {
            let bin = &order[starts[o] as usize..starts[o + 1] as usize];
            assert!(bin.len() > 100, "octant {o}: {}", bin.len());
            for w in bin.windows(2) {
                let (a, b) = (&rays[w[0] as usize], &rays[w[1] as usize]);
                assert_eq!(octant(a.dir), o);
                assert_eq!(octant(b.dir), o);
                let (ka, kb) = (code(a.origin), code(b.origin));
                assert!(ka < kb || (ka == kb && w[0] < w[1]), "{w:?}");
            }
        }
    }
}

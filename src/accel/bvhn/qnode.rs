//! The compressed N-wide node: child boxes quantised to 8 bits per plane against the
//! node's own box, as in Embree's compressed BVH8 (`QBVH8`, Wald et al., "Embree: A
//! Kernel Framework for Efficient CPU Ray Tracing", ACM TOG 33(4), 2014) and Ylitie,
//! Karras and Laine, "Efficient Incoherent Ray Traversal on GPUs Through Compressed
//! Wide BVHs" (HPG 2017): half (BVH8) or a quarter (BVH4) of the exact node's bytes.
//!
//! Per axis the node stores an origin (the smallest child minimum) and a power-of-two
//! step; a child's plane is `origin + q * step` for its 8-bit `q`
//! ([`dequantize`](crate::simd::quant::dequantize)). Rounding is conservative, the
//! property that keeps traversal watertight: a minimum plane is rounded down and a
//! maximum plane up, each checked with the very expression the traversal decodes with,
//! so every quantised box contains the exact one and no ray that enters a child's exact
//! box misses its quantised box (the slab test's distances are monotone in the plane;
//! see `QNode::quantize`). The leaves and their watertight triangle test are unchanged,
//! so the hits are the exact tree's, bit for bit; only some extra boxes are entered.
//!
//! An axis whose child bounds are not finite cannot be quantised; its step is NaN, so
//! its planes decode to NaN, which the slab tests (`maxps`/`minps` fold NaN away) read
//! as an unbounded slab: conservative again.
//!
//! Not the default, and no size-based choice either: at 10^6 on the AVX-512 host
//! (big19, 2026-11-28, `stream_profile /tmp/m1e6.obj MODE W 5`, 1 thread, load ~4, `cpu`
//! 0.66, 5 interleaved rounds, Mrays/s medians) bvh8c-packet primary 9.26/8.68/8.62/
//! 10.94/9.22 against bvh8-packet 11.60/8.75/8.49/10.99/11.23, shadow 3.70/2.84/3.87/
//! 3.64/3.07 against 3.78/3.20/3.15/4.11/3.99 (52.4 against 62.9 bytes per triangle).

use super::node::{BvhNode, EMPTY_CHILD, WideNode};
use crate::simd::quant::{dequantize, dequantize_planes};

/// A compressed node of an N-wide BVH: two cache lines for N = 8, one for N = 4.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub struct QNode<const N: usize> {
    /// Per axis: the plane of offset 0 (the smallest minimum of the children).
    pub origin: [f32; 3],
    /// Per axis: the step between offsets, a power of two (NaN: the axis is not
    /// quantised).
    pub scale: [f32; 3],
    /// Offsets of the planes `min_x, min_y, min_z, max_x, max_y, max_z`, one lane per
    /// child; an unused slot holds `255` for its minima and `0` for its maxima.
    pub q: [[u8; N]; 6],
    /// Child references, as in [`BvhNode::children`].
    pub children: [u32; N],
}

/// A compressed 4-wide node: 24 bytes of origin and steps, 24 of offsets, 16 of
/// references; one cache line.
pub type Bvh4QNode = QNode<4>;
/// A compressed 8-wide node: 104 bytes, padded to two cache lines.
pub type Bvh8QNode = QNode<8>;

const _: () = assert!(std::mem::size_of::<Bvh4QNode>() == 64);
const _: () = assert!(std::mem::align_of::<Bvh4QNode>() == 64);
const _: () = assert!(std::mem::size_of::<Bvh8QNode>() == 128);
const _: () = assert!(std::mem::align_of::<Bvh8QNode>() == 64);
const _: () = assert!(std::mem::offset_of!(Bvh8QNode, children) == 72);

/// Planes decoded from a [`QNode`] for one visit.
pub struct Decoded<const N: usize>([[f32; N]; 6]);

impl<const N: usize> std::ops::Deref for Decoded<N> {
    type Target = [[f32; N]; 6];
    #[inline(always)]
    fn deref(&self) -> &[[f32; N]; 6] {
        &self.0
    }
}

/// `2^e` for `e` in `-126..=127`.
fn pow2(e: i32) -> f32 {
    f32::from_bits(((e + 127) as u32) << 23)
}

/// The smallest power-of-two step with `origin + 255 * step >= hi` (as
/// [`dequantize`] rounds it), for a finite `origin <= hi`.
fn step_for(origin: f32, hi: f32) -> f32 {
    let extent = (hi - origin) / 255.0;
    let mut e = if extent > 0.0 {
        // saturating: an infinite extent (overflow) gives the largest exponent
        (extent.log2().ceil() as i32).clamp(-126, 127)
    } else {
        -126
    };
    while e < 127 && dequantize(origin, pow2(e), 255) < hi {
        e += 1;
    }
    // 255 * 2^127 overflows to +inf, which covers any `hi`.
    while e > -126 && dequantize(origin, pow2(e - 1), 255) >= hi {
        e -= 1;
    }
    pow2(e)
}

/// The largest offset whose plane is at most `x` (offset 0, the origin, always is).
fn round_down(origin: f32, step: f32, x: f32) -> u8 {
    let mut q = ((x - origin) / step).floor().clamp(0.0, 255.0) as u8;
    while q > 0 && dequantize(origin, step, q) > x {
        q -= 1;
    }
    while q < 255 && dequantize(origin, step, q + 1) <= x {
        q += 1;
    }
    q
}

/// The smallest offset whose plane is at least `x` (offset 255 always is).
fn round_up(origin: f32, step: f32, x: f32) -> u8 {
    let mut q = ((x - origin) / step).ceil().clamp(0.0, 255.0) as u8;
    while q < 255 && dequantize(origin, step, q) < x {
        q += 1;
    }
    while q > 0 && dequantize(origin, step, q - 1) >= x {
        q -= 1;
    }
    q
}

impl<const N: usize> QNode<N> {
    /// Quantises the child boxes of `node` conservatively: per axis the origin is the
    /// smallest child minimum, the step the smallest power of two that reaches the
    /// largest maximum within 255 steps; each minimum rounds down and each maximum up,
    /// verified with [`dequantize`] itself.
    pub fn quantize(node: &BvhNode<N>) -> Self {
        let mut out = QNode {
            origin: [0.0; 3],
            scale: [1.0; 3],
            q: [[255; N], [255; N], [255; N], [0; N], [0; N], [0; N]],
            children: node.children,
        };
        let used: Vec<usize> = (0..N)
            .filter(|&c| node.children[c] != EMPTY_CHILD)
            .collect();
        if used.is_empty() {
            return out;
        }
        for a in 0..3 {
            let lo = used
                .iter()
                .map(|&c| node.planes[a][c])
                .fold(f32::INFINITY, f32::min);
            let hi = used
                .iter()
                .map(|&c| node.planes[a + 3][c])
                .fold(f32::NEG_INFINITY, f32::max);
            let finite = used
                .iter()
                .all(|&c| node.planes[a][c].is_finite() && node.planes[a + 3][c].is_finite());
            if !finite {
                out.scale[a] = f32::NAN;
                continue;
            }
            let step = step_for(lo, hi);
            out.origin[a] = lo;
            out.scale[a] = step;
            for &c in &used {
                out.q[a][c] = round_down(lo, step, node.planes[a][c]);
                out.q[a + 3][c] = round_up(lo, step, node.planes[a + 3][c]);
            }
        }
        out
    }
}

impl<const N: usize> WideNode<N> for QNode<N> {
    const COMPRESSED: bool = true;
    type Planes<'a> = Decoded<N>;

    fn from_exact(node: &BvhNode<N>) -> Self {
        Self::quantize(node)
    }
    #[inline(always)]
    fn planes(&self) -> Decoded<N> {
        Decoded(dequantize_planes(&self.origin, &self.scale, &self.q))
    }
    #[inline(always)]
    fn children(&self) -> &[u32; N] {
        &self.children
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every rounded plane lies outside the exact box, and is the tightest offset that
    /// does, for boxes at awkward magnitudes (tiny, huge, straddling zero, flat).
    #[test]
    fn quantised_planes_are_conservative_and_tight() {
        let mut s = 3u32;
        let mut r = move || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s as f32 / u32::MAX as f32
        };
        let mut checked = 0;
        for trial in 0..400 {
            let mag = [1e-30f32, 1e-3, 1.0, 1e4, 1e30][trial % 5];
            let off = [0.0f32, -0.5, 1e3][trial % 3] * mag;
            let mut node = BvhNode::<8> {
                planes: [[f32::INFINITY; 8]; 6],
                children: [EMPTY_CHILD; 8],
            };
            for c in 0..(1 + trial % 8) {
                for a in 0..3 {
                    let x = off + (r() - 0.5) * mag;
                    let w = if trial % 11 == 0 { 0.0 } else { r() * mag };
                    node.planes[a][c] = x;
                    node.planes[a + 3][c] = x + w;
                }
                node.children[c] = c as u32;
            }
            let qn = QNode::quantize(&node);
            let p = qn.planes();
            for c in (0..8).filter(|&c| node.children[c] != EMPTY_CHILD) {
                for a in 0..3 {
                    let (lo, hi) = (node.planes[a][c], node.planes[a + 3][c]);
                    assert!(p[a][c] <= lo && p[a + 3][c] >= hi, "trial {trial} axis {a}");
                    let (o, st) = (qn.origin[a], qn.scale[a]);
                    let (ql, qh) = (qn.q[a][c], qn.q[a + 3][c]);
                    assert!(ql == 255 || dequantize(o, st, ql + 1) > lo, "not tight");
                    assert!(qh == 0 || dequantize(o, st, qh - 1) < hi, "not tight");
                    checked += 1;
                }
            }
        }
        assert!(checked > 3000, "{checked}");
    }

    /// A non-finite child bound leaves its axis unquantised: NaN planes, which the slab
    /// tests read as an unbounded slab.
    #[test]
    fn non_finite_bounds_decode_to_an_unbounded_slab() {
        let mut node = BvhNode::<4> {
            planes: [[f32::INFINITY; 4]; 6],
            children: [EMPTY_CHILD; 4],
        };
        for a in 0..3 {
            node.planes[a][0] = -1.0;
            node.planes[a + 3][0] = 1.0;
        }
        node.planes[3][0] = f32::INFINITY;
        node.children[0] = 0;
        let qn = QNode::quantize(&node);
        let p = qn.planes();
        assert!(p[0][0].is_nan() && p[3][0].is_nan());
        assert!(p[1][0] <= -1.0 && p[4][0] >= 1.0);
    }
}

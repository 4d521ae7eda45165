//! Dequantisation of compressed BVH nodes (`accel::bvhn::QNode`): child box planes
//! stored as 8-bit offsets from the node's origin in steps of a per-axis power of two,
//! turned back into `f32` planes for the ordinary slab tests.
//!
//! One expression, [`dequantize`], serves both the encoder (which checks every rounded
//! plane against the exact one with it) and the traversal kernels (which decode whole
//! nodes with [`dequantize_planes`], the same operations lane by lane: Rust never fuses
//! the multiply and the add), so a plane the encoder verified to lie outside the exact
//! box is, bit for bit, the plane the traversal tests.

/// The plane of quantised offset `q`: `origin + q * scale`, rounded as written.
#[inline(always)]
pub fn dequantize(origin: f32, scale: f32, q: u8) -> f32 {
    origin + f32::from(q) * scale
}

/// A node's six plane arrays (`min_x, min_y, min_z, max_x, max_y, max_z`, one lane per
/// child) from its quantised offsets: plane array `p` uses axis `p % 3`'s origin and
/// scale. Written as plain loops over fixed sizes, which the compiler turns into a few
/// byte-to-float conversions and multiply-adds per array.
#[inline(always)]
pub fn dequantize_planes<const N: usize>(
    origin: &[f32; 3],
    scale: &[f32; 3],
    q: &[[u8; N]; 6],
) -> [[f32; N]; 6] {
    let mut out = [[0.0f32; N]; 6];
    for (p, row) in out.iter_mut().enumerate() {
        let (o, s) = (origin[p % 3], scale[p % 3]);
        for (x, &k) in row.iter_mut().zip(&q[p]) {
            *x = dequantize(o, s, k);
        }
    }
    out
}

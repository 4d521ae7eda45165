//! The fixed-capacity traversal stacks of the single-ray and packet kernels, and the
//! far-to-near insertion of the children a node pushes (packet and stream kernels).

/// Single-ray traversal stack capacity. A node pushes at most N - 1 entries per level it
/// descends and the BVH2 depth bound (`bvh2::STACK_SIZE`) bounds the levels, so
/// 7 x 128 entries cover an 8-wide tree of any shape (checked at build time).
pub(super) const SINGLE_STACK: usize = 7 * crate::accel::bvh2::STACK_SIZE + 1;

/// Packet traversal stack capacity (an entry holds a lane vector of entry distances, so
/// this is kept smaller). A tree whose worst path needs more (a path through more than
/// 36 full 8-wide nodes) traces its packets ray by ray.
pub(super) const PACKET_STACK: usize = 256;

/// A fixed-size traversal stack that is not zero-filled per ray (a 3 KB memset per ray
/// cost 17 % of single-ray time). Entries below `len` are always initialised.
pub(super) struct Stack<T: Copy, const CAP: usize> {
    items: [std::mem::MaybeUninit<T>; CAP],
    pub(super) len: usize,
}

impl<T: Copy, const CAP: usize> Stack<T, CAP> {
    #[inline(always)]
    pub(super) fn new() -> Self {
        Stack {
            items: [const { std::mem::MaybeUninit::uninit() }; CAP],
            len: 0,
        }
    }

    #[inline(always)]
    pub(super) fn push(&mut self, x: T) {
        self.items[self.len].write(x);
        self.len += 1;
    }

    #[inline(always)]
    pub(super) fn pop(&mut self) -> Option<T> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        // SAFETY: every slot below the old `len` was written by `push`.
        Some(unsafe { self.items[self.len].assume_init() })
    }
}

/// The packet kernels' stack: node references and lane vectors of entry distances in
/// two arrays rather than one array of `(u32, L)` pairs.
///
/// Why: a pair is 128 bytes for 16 lanes (60 of them padding), and pushing one was
/// compiled as a copy of the whole pair in 32-byte halves; the pop that followed soon
/// after read the lanes back with one 64-byte load, which cannot be forwarded from two
/// smaller stores and waits for them to reach the cache (`perf annotate` of
/// `examples/stream_profile bunny.obj bvh8-packet primary 80`, AVX-512: 2.9 % of
/// `packet_closest`'s samples on that copy). Here a push stores the lanes whole.
pub(super) struct LaneStack<L: Copy, const CAP: usize> {
    nodes: [std::mem::MaybeUninit<u32>; CAP],
    enters: [std::mem::MaybeUninit<L>; CAP],
    len: usize,
}

impl<L: Copy, const CAP: usize> LaneStack<L, CAP> {
    #[inline(always)]
    pub(super) fn new() -> Self {
        LaneStack {
            nodes: [const { std::mem::MaybeUninit::uninit() }; CAP],
            enters: [const { std::mem::MaybeUninit::uninit() }; CAP],
            len: 0,
        }
    }

    #[inline(always)]
    pub(super) fn push(&mut self, node: u32, enter: L) {
        self.nodes[self.len].write(node);
        self.enters[self.len].write(enter);
        self.len += 1;
    }

    #[inline(always)]
    pub(super) fn pop(&mut self) -> Option<(u32, L)> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        // SAFETY: every slot below the old `len` was written by `push`.
        unsafe {
            Some((
                self.nodes[self.len].assume_init(),
                self.enters[self.len].assume_init(),
            ))
        }
    }
}

impl<const CAP: usize> Stack<(u32, f32), CAP> {
    /// Insertion-sorts the entries from `base` up by decreasing distance, so the nearest
    /// is popped first. Equal distances keep their push order.
    #[inline(always)]
    pub(super) fn sort_top_far_to_near(&mut self, base: usize) {
        // SAFETY: every slot below `len` was written by `push`.
        let items = unsafe {
            std::slice::from_raw_parts_mut(self.items.as_mut_ptr().cast::<(u32, f32)>(), self.len)
        };
        let run = &mut items[base..];
        for i in 1..run.len() {
            let x = run[i];
            let mut j = i;
            while j > 0 && run[j - 1].1 < x.1 {
                run[j] = run[j - 1];
                j -= 1;
            }
            run[j] = x;
        }
    }
}

/// Inserts child `c` with entry distance `key` into `order[..*n]`, kept sorted far to
/// near (so pushing it in order leaves the nearest on top), and counts it in `n`.
/// Equal keys keep their insertion order.
#[inline(always)]
pub(super) fn insert_far_to_near<const N: usize>(
    order: &mut [(usize, f32); N],
    n: &mut usize,
    c: usize,
    key: f32,
) {
    let mut j = *n;
    while j > 0 && order[j - 1].1 < key {
        order[j] = order[j - 1];
        j -= 1;
    }
    order[j] = (c, key);
    *n += 1;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::{F16, Lanes};

    /// The packet stack gives back what was pushed, last in first out, each node with
    /// its own lanes (every lane distinct), and nothing once empty.
    #[test]
    fn lane_stack_pops_pushes_in_reverse_with_their_lanes() {
        let lanes = |k: u32| {
            let mut a = [0.0f32; 16];
            for (i, x) in a.iter_mut().enumerate() {
                *x = (k * 16 + i as u32) as f32;
            }
            F16::from_array(a)
        };
        let mut s: LaneStack<F16, 8> = LaneStack::new();
        assert!(s.pop().is_none());
        for k in 0..8 {
            s.push(100 + k, lanes(k));
        }
        for k in (5..8).rev() {
            let (node, e) = s.pop().expect("pushed");
            assert_eq!(node, 100 + k);
            assert_eq!(e.to_array(), lanes(k).to_array());
        }
        s.push(7, lanes(40));
        assert_eq!(
            s.pop().map(|(n, e)| (n, e.to_array())),
            Some((7, lanes(40).to_array()))
        );
        for k in (0..5).rev() {
            assert_eq!(s.pop().map(|(n, _)| n), Some(100 + k));
        }
        assert!(s.pop().is_none());
    }
}

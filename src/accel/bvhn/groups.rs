//! The leaves' triangle groups: one array whose first group starts on a cache line.
//!
//! A [`TriGroup4`] is 160 bytes, two and a half cache lines, aligned to 16. In an array
//! that starts on a line (or half-way into one) every group lies in three lines; the
//! arrays the collapse wrote before came from `malloc` (or the build's reference array,
//! taken over by `realloc`), whose large blocks start 16 bytes past a page, so every
//! second group began 48 bytes into a line and spread over four. The leaf tests read
//! the fourth line (the ids, the group's last 16 bytes) after the corners, and the
//! traversals' prefetch of a group's three lines from its start missed it.
//!
//! [`TriGroups`] keeps the groups in 16-byte chunks (the alignment of `TriGroup4` and
//! of the build's references, so the build's dead reference array still serves as
//! their memory, `SpareRefs`) and skips up to three chunks at the front so that group
//! 0 starts on a line; it reads as a `[TriGroup4]` slice.

use crate::accel::sah_build::SpareRefs;
use crate::simd::kernels::TriGroup4;
use std::mem::{align_of, offset_of, size_of};

/// The array's unit: 16 bytes, one lane row of a group (`v[corner][axis]` or `ids`).
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(16))]
struct Chunk([u32; 4]);

/// Chunks per group.
const CHUNKS: usize = size_of::<TriGroup4>() / size_of::<Chunk>();
/// The cache line the first group starts on.
pub(super) const LINE: usize = 64;
/// The most chunks skipped to reach a line.
const MAX_SKIP: usize = LINE / size_of::<Chunk>() - 1;

// A group is exactly its nine corner rows and its ids row, in that order, with no
// padding, and needs no more alignment than a chunk gives.
const _: () = assert!(CHUNKS * size_of::<Chunk>() == size_of::<TriGroup4>());
const _: () = assert!(CHUNKS == 10);
const _: () = assert!(align_of::<TriGroup4>() == align_of::<Chunk>());
const _: () = assert!(offset_of!(TriGroup4, v) == 0);
const _: () = assert!(offset_of!(TriGroup4, ids) == 9 * size_of::<Chunk>());

/// A group as the chunks it is stored in.
fn chunks(g: &TriGroup4) -> [Chunk; CHUNKS] {
    let mut c = [Chunk::default(); CHUNKS];
    for (dst, row) in c.iter_mut().zip(g.v.iter().flatten()) {
        *dst = Chunk(row.map(f32::to_bits));
    }
    c[CHUNKS - 1] = Chunk(g.ids);
    c
}

/// Chunks to skip from `p` (16-byte aligned) to the next line boundary.
fn skip_at(p: *const Chunk) -> usize {
    (p as usize).wrapping_neg() % LINE / size_of::<Chunk>()
}

/// Triangle groups whose first one starts on a cache line (see the module docs).
///
/// Invariant: `buf[..skip]` is padding, `buf[skip..]` holds whole groups, and where
/// `buf` has memory `buf.as_ptr() + skip` is on a line.
#[derive(Default)]
pub(super) struct TriGroups {
    buf: Vec<Chunk>,
    skip: usize,
}

impl TriGroups {
    /// No groups, no memory.
    pub(super) fn new() -> Self {
        Self::default()
    }

    /// Room for `groups` groups in `spare`'s memory (see [`SpareRefs::into_vec`]).
    pub(super) fn in_spare(spare: SpareRefs, groups: usize) -> Self {
        let mut g = TriGroups {
            buf: spare.into_vec(groups * CHUNKS + MAX_SKIP),
            skip: 0,
        };
        g.realign();
        g
    }

    /// Whether no memory is held yet.
    pub(super) fn is_unallocated(&self) -> bool {
        self.buf.capacity() == 0
    }

    /// Room for `more` groups after these, with the first still on a line.
    pub(super) fn reserve(&mut self, more: usize) {
        let need = MAX_SKIP + CHUNKS * (self.len() + more);
        if need > self.buf.capacity() {
            self.buf.reserve(need - self.buf.len());
            self.realign();
        }
    }

    /// Appends a group.
    pub(super) fn push(&mut self, g: &TriGroup4) {
        if self.buf.len() + CHUNKS > self.buf.capacity() {
            // doubling, as `Vec::push` does
            self.reserve(self.len().max(4));
        }
        self.buf.extend_from_slice(&chunks(g));
    }

    /// Appends `other`'s groups.
    pub(super) fn append(&mut self, other: &TriGroups) {
        self.reserve(other.len());
        self.buf.extend_from_slice(&other.buf[other.skip..]);
    }

    /// Moves the groups to the line boundary of the current memory (after it moved).
    fn realign(&mut self) {
        let want = skip_at(self.buf.as_ptr());
        if want == self.skip {
            return;
        }
        let n = self.buf.len() - self.skip;
        if want > self.skip {
            // within the capacity (`MAX_SKIP` chunks are always spare): no reallocation
            self.buf.resize(want + n, Chunk::default());
        }
        self.buf.copy_within(self.skip..self.skip + n, want);
        self.buf.truncate(want + n);
        self.skip = want;
    }
}

impl std::ops::Deref for TriGroups {
    type Target = [TriGroup4];

    fn deref(&self) -> &[TriGroup4] {
        let groups = &self.buf[self.skip..];
        // SAFETY: `groups` is `len / CHUNKS` whole groups, each written by `chunks` from
        // a `TriGroup4`: its nine corner rows and its ids, in the field order and with
        // no padding (asserted above), and any bits are valid `f32`s and `u32`s; a
        // chunk's alignment is a group's (asserted), and the slice borrows `self.buf`.
        unsafe {
            std::slice::from_raw_parts(groups.as_ptr().cast::<TriGroup4>(), groups.len() / CHUNKS)
        }
    }
}

impl<'a> IntoIterator for &'a TriGroups {
    type Item = &'a TriGroup4;
    type IntoIter = std::slice::Iter<'a, TriGroup4>;

    fn into_iter(self) -> Self::IntoIter {
        self.iter()
    }
}

#[cfg(test)]
mod tests {
    use super::super::tree::wide_build_options;
    use super::*;
    use crate::accel::Triangles;
    use crate::accel::sah_build::build_tree_keeping_refs;
    use glam::Vec3;

    /// A group with every corner and id distinct (`k` picks the values), lane 3 unused
    /// when `k` is odd.
    fn group(k: usize) -> TriGroup4 {
        let mut g = TriGroup4::EMPTY;
        for lane in 0..4 - k % 2 {
            let f = |c: usize| {
                let base = (k * 100 + lane * 10 + c) as f32;
                Vec3::new(base, base + 0.25, base + 0.5)
            };
            g.set(lane, (k * 4 + lane) as u32, [f(0), f(1), f(2)]);
        }
        g
    }

    fn bits(groups: &[TriGroup4]) -> Vec<u32> {
        let mut b = Vec::new();
        for g in groups {
            b.extend(g.v.iter().flatten().flatten().map(|x| x.to_bits()));
            b.extend(g.ids);
        }
        b
    }

    fn assert_on_a_line(g: &TriGroups, what: &str) {
        if !g.is_empty() {
            assert_eq!(
                g.as_ptr() as usize % LINE,
                0,
                "{what}: first group off a line"
            );
        }
    }

    /// Pushes through every reallocation, appends and reservations keep every bit
    /// of every group (NaN corners of unused lanes included), in order, with the
    /// first group on a line throughout.
    #[test]
    fn groups_keep_their_bits_and_start_on_a_line() {
        let want: Vec<TriGroup4> = (0..1000).map(group).collect();
        let mut g = TriGroups::new();
        assert!(g.is_unallocated() && g.is_empty());
        for (i, x) in want.iter().enumerate() {
            g.push(x);
            assert_on_a_line(&g, "push");
            if i % 97 == 0 {
                g.reserve(i);
                assert_on_a_line(&g, "reserve");
            }
            assert_eq!(g.len(), i + 1);
        }
        assert_eq!(bits(&g), bits(&want));
        let mut h = TriGroups::new();
        h.push(&want[0]);
        for part in want[1..].chunks(333) {
            let mut p = TriGroups::new();
            for x in part {
                p.push(x);
            }
            h.append(&p);
            assert_on_a_line(&h, "append");
        }
        assert_eq!(bits(&h), bits(&want));
        assert_eq!((&h).into_iter().count(), want.len());
    }

    /// Every start of the memory (0 to 3 chunks past a line) is moved to the line,
    /// contents kept: what `realign` does after a reallocation.
    #[test]
    fn realign_moves_the_groups_to_the_line() {
        let want: Vec<TriGroup4> = (0..7).map(group).collect();
        for offset in 0..=MAX_SKIP {
            let mut g = TriGroups::new();
            g.reserve(want.len() + 1);
            for x in &want {
                g.push(x);
            }
            // shift the groups off the line by `offset` chunks, as a new block would be
            let start = g.skip;
            let n = g.buf.len() - start;
            let at = (start + offset) % (MAX_SKIP + 1);
            g.buf.resize(n + at.max(start), Chunk::default());
            g.buf.copy_within(start..start + n, at);
            g.buf.truncate(at + n);
            g.skip = at;
            g.realign();
            assert_on_a_line(&g, "realign");
            assert_eq!(bits(&g), bits(&want), "offset {offset}");
        }
    }

    /// Groups made from a build's spare reference array start on a line too (a large
    /// block from `malloc` starts 16 bytes past a page).
    #[test]
    fn groups_in_spare_memory_start_on_a_line() {
        let corners: Vec<[Vec3; 3]> = (0..5000)
            .map(|i| {
                let p = Vec3::new(i as f32, (i % 7) as f32, 0.0);
                [p, p + Vec3::X, p + Vec3::Y]
            })
            .collect();
        let tris = Triangles::from_corners(&corners);
        let (_, _, spare) = build_tree_keeping_refs(&tris, wide_build_options(true));
        let want: Vec<TriGroup4> = (0..50_000).map(group).collect();
        let mut g = TriGroups::in_spare(spare, want.len());
        for x in &want {
            g.push(x);
        }
        assert_on_a_line(&g, "spare");
        assert_eq!(bits(&g), bits(&want));
    }
}

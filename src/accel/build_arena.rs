//! A build-scoped arena for the binned-SAH builder's child pairs: chunks of up to 16 MiB,
//! advised for transparent huge pages, from which the build's threads claim blocks of
//! 64 slots under a lock, instead of one `malloc` per interior node.
//!
//! Why (issue 12, session 27): every interior node of the build tree held its two
//! children in a boxed 96-byte pair: 2.6 million `malloc`s at 10^7 triangles, in heap
//! pages that are fresh in every build (glibc trims the freed heap's top, and each
//! rayon thread has its arena), freed one by one afterwards. `perf record -e
//! page-faults` of `examples/build_time 10000000 1 2`: 27 % of the build's page faults
//! were `sysmalloc` growing the heaps for the pairs; `perf record -e cpu-clock`: `malloc`,
//! `_int_free`, `malloc_consolidate` and the pairs' drop 6.4 % of a 2-thread build's
//! samples, on top of the kernel zeroing those pages. Here the pairs land in 2 MiB
//! pages (on this host a fresh 4 KiB page costs 5-40 us to touch in its slow state, a
//! 2 MiB page ~0.1-0.2 ms: `pages::huge`), and the whole tree is freed at once (its
//! recursive drop had taken 10-12 ms of a 10^6 build on one thread, then was spread
//! over rayon tasks: issue 12, helper bd25, 2026-11-29, `build_time 1000000 5 2`).
//!
//! helper big19 (session 19, recorded in `sah_build.rs`'s header) had tried a bump
//! arena without huge pages (one worst-case array, then 256 KiB heap chunks) and found
//! repeated 1-thread 10^6 builds no faster; so are these (below), the gain is at 2
//! threads and in a fresh process.
//!
//! Chunks rather than one reservation for the largest possible tree (one pair fewer
//! than primitives, 96 bytes each), measured (session 27, AVX-512, 1 thread): the single
//! reservation was mapped afresh by every build, and a 10^7 build, whose ~320 MB of
//! pairs the boxed pairs had found in the heap pages of the build before, then paid
//! for fresh huge pages (`examples/build_time 10000000 2 1`, 3 interleaved rounds, wall
//! ms medians 4,086 / 3,921 / 4,128 boxed against 4,551 / 4,618 / 4,613), while a
//! single 10^7 build in a fresh process was level (`render` of the `tessellated`
//! generator at 10^7 triangles, build ms 5,578 / 4,536 against 5,348 / 4,640) and 10^6
//! builds were faster (fresh process, 4 rounds: 520 / 436 / 613 / 440 against 413 /
//! 407 / 379 / 383 ms). Chunks below glibc's largest mmap threshold come from the heap
//! once a build has freed its large arrays, as the boxes did. The chunks against the
//! boxes (interleaved, wall ms medians): `build_time 10000000 2 1` 3,452 / 3,586 against
//! 3,509 / 3,530; `build_time 1000000 7 1` 342 / 333 against 338 / 337; `build_time
//! 1000000 7 2` 188 / 178 against 178 / 161; a 10^6 build at 1 thread in a fresh process
//! 409 / 379 / 561 / 387 against 365 / 347 / 410 / 361 ms.
//!
//! Kept between builds (issue 12, helper bc28, session 28): a chunk of 4 MiB and more is
//! a `pages::LargeVec`'s room (a 2 MiB-aligned mapping advised for huge pages), whose
//! mapping goes back to `pages::array`'s kept list when the arena drops it, for the
//! next build's chunks. The heap chunks had been faulted in largely 4 KiB at a time
//! all the same (`perf record -e page-faults -c 1` of `build_time 10000000 1 2`:
//! ~11,000 faults per 10^7 build in `Arena::push`; chunks made 2 MiB-aligned with the
//! heap's `memalign` changed nothing, 23.0k -> 22.5k over two builds, so the cause is
//! glibc's per-thread heaps, not the chunks' edges). With the kept mappings:
//! page faults per 10^7 2-thread build 6-10k -> 1.1-2.1k (with the `ids` array advised,
//! `sah_build::zeroed_ids`).

use crate::pages::{LargeVec, advise_huge_pages};
use std::alloc::Layout;
use std::marker::PhantomData;
use std::mem::MaybeUninit;
use std::ptr::NonNull;
use std::sync::Mutex;

/// Slots a cursor claims at once: one lock per 64 pairs (6 KiB of `BuildNode` pairs),
/// and at most 63 slots left unused per cursor.
const BLOCK: usize = 64;

/// The largest chunk: half of glibc's largest mmap threshold (`pages::ALWAYS_MAPPED_BYTES`),
/// so that once that threshold has risen, chunks come from the heap and reuse its pages.
const CHUNK_BYTES: usize = 16 << 20;

/// Values of one type, written once each and never moved, freed together with the
/// arena (their destructors are not run: `T` must not need one).
pub(super) struct Arena<T> {
    chunks: Mutex<Chunks<T>>,
    /// Slots per chunk.
    chunk_values: usize,
    _owns: PhantomData<T>,
}

/// The unit a chunk's memory is counted in: 16 bytes, aligned as the builder's nodes.
#[derive(Clone, Copy)]
#[repr(C, align(16))]
struct Unit([u8; 16]);

struct Chunks<T> {
    /// Every chunk allocated (its values are in the spare room of a `LargeVec`, which
    /// never holds any value of its own: nothing is read through it).
    list: Vec<LargeVec<Unit>>,
    /// The first unclaimed slot of the last chunk, and its end.
    next: *mut MaybeUninit<T>,
    end: *mut MaybeUninit<T>,
}

// SAFETY: the arena hands each slot to one cursor only (claimed under the lock), a
// slot is written once before any reference to it exists, and values are only read
// through shared references afterwards; `T: Send + Sync` for the values to move in
// from any thread and be read from any thread.
unsafe impl<T: Send + Sync> Sync for Arena<T> {}
// SAFETY: the arena owns its chunks and values outright.
unsafe impl<T: Send + Sync> Send for Arena<T> {}

/// A run of slots `[at, end)` claimed by one thread and not yet used.
pub(super) struct Cursor<T> {
    at: *mut MaybeUninit<T>,
    end: *mut MaybeUninit<T>,
}

// SAFETY: the slots of a cursor belong to it alone; moving it to another thread moves
// that exclusive claim.
unsafe impl<T: Send> Send for Cursor<T> {}

impl<T> Cursor<T> {
    /// A cursor with nothing claimed: its first push claims a block.
    pub(super) fn empty() -> Self {
        Cursor {
            at: std::ptr::null_mut(),
            end: std::ptr::null_mut(),
        }
    }
}

/// A value in an [`Arena`]: a shared reference without a lifetime, valid while the
/// arena lives (the owner of both keeps them together: `sah_build::BuildTree`).
pub(super) struct ArenaRef<T>(NonNull<T>);

// SAFETY: an `ArenaRef` is a shared reference into an arena whose values are never
// written again; sending or sharing it is sending or sharing a `&T`.
unsafe impl<T: Sync> Send for ArenaRef<T> {}
// SAFETY: as above.
unsafe impl<T: Sync> Sync for ArenaRef<T> {}

impl<T> std::ops::Deref for ArenaRef<T> {
    type Target = T;

    #[inline(always)]
    fn deref(&self) -> &T {
        // SAFETY: the slot was written before this reference was made (`Arena::push`)
        // and is never written again; `push`'s contract keeps the arena alive while
        // the reference is used.
        unsafe { self.0.as_ref() }
    }
}

impl<T> Arena<T> {
    /// An arena for about `values` values (its first chunk holds them all when they
    /// fit in [`CHUNK_BYTES`]; more chunks follow as needed).
    pub(super) fn new(values: usize) -> Self {
        Self::with_chunk_bytes(values, CHUNK_BYTES)
    }

    fn with_chunk_bytes(values: usize, chunk_bytes: usize) -> Self {
        const { assert!(!std::mem::needs_drop::<T>(), "arena values are not dropped") };
        const { assert!(size_of::<T>() > 0, "no zero-sized values") };
        let most = (chunk_bytes / size_of::<T>()).max(BLOCK);
        Arena {
            chunks: Mutex::new(Chunks {
                list: Vec::new(),
                next: std::ptr::null_mut(),
                end: std::ptr::null_mut(),
            }),
            chunk_values: values.clamp(BLOCK, most),
            _owns: PhantomData,
        }
    }

    /// Moves `value` into the arena, in the next slot of `cursor` (claiming a block
    /// when it has none left), and returns a reference to it.
    ///
    /// # Safety
    /// The returned reference must not be dereferenced after the arena is dropped, and
    /// `cursor` must have been made for this arena.
    #[inline]
    pub(super) unsafe fn push(&self, cursor: &mut Cursor<T>, value: T) -> ArenaRef<T> {
        if cursor.at == cursor.end {
            *cursor = self.claim();
        }
        let slot = cursor.at;
        // SAFETY: `at < end`: a slot of a chunk, claimed by this cursor alone and not
        // written before; after the write it holds an initialised `T`.
        unsafe {
            cursor.at = slot.add(1);
            slot.write(MaybeUninit::new(value));
            ArenaRef(NonNull::new_unchecked(slot.cast::<T>()))
        }
    }

    /// The next block of slots, from a new chunk when the last one has fewer left.
    fn claim(&self) -> Cursor<T> {
        let mut c = self.chunks.lock().unwrap_or_else(|e| e.into_inner());
        // `next` and `end` lie in the same chunk, `next <= end` (or both are null).
        let left = (c.end as usize - c.next as usize) / size_of::<T>();
        if left < BLOCK {
            const { assert!(align_of::<T>() <= align_of::<Unit>()) };
            let bytes = Layout::array::<T>(self.chunk_values)
                .expect("arena chunk size")
                .size();
            // From 4 MiB a huge-page mapping of its own, kept for the next build's
            // chunks when this arena drops it (`pages::LargeVec`); smaller ones on the
            // heap.
            let mut chunk = LargeVec::<Unit>::with_capacity(bytes.div_ceil(size_of::<Unit>()));
            if !chunk.is_mapped() {
                advise_huge_pages(chunk.spare_capacity_mut().as_mut_ptr().cast(), bytes);
            }
            let ptr = chunk
                .spare_capacity_mut()
                .as_mut_ptr()
                .cast::<MaybeUninit<T>>();
            c.list.push(chunk);
            c.next = ptr;
            // SAFETY: one past the chunk's last slot.
            c.end = unsafe { ptr.add(self.chunk_values) };
        }
        let at = c.next;
        // SAFETY: at least BLOCK slots remain before `end`.
        c.next = unsafe { at.add(BLOCK) };
        Cursor { at, end: c.next }
    }

    /// Chunks allocated so far.
    #[cfg(test)]
    fn chunk_count(&self) -> usize {
        self.chunks.lock().map_or(0, |c| c.list.len())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Values pushed from several threads, each with a fresh cursor every 100 values
    /// (as the builder starts one for every subtree handed to another task), read back
    /// as pushed, through chunks that fill up (small ones here) and a chunk as large as
    /// asked for.
    #[test]
    fn values_read_back_from_every_thread_across_chunks() {
        // Every cursor below claims two blocks of 64 for its 100 values: 80 claims.
        // Chunks of one block (no hint: the smallest chunk) take a chunk per claim;
        // chunks of 150 slots hold two blocks, and a claim that finds fewer than a block
        // left starts a new chunk; a chunk of a million slots holds every claim.
        for (hint, chunk_bytes, chunks) in [
            (0usize, 16 * 200, 80),
            (150, 16 << 20, 40),
            (1 << 20, 16 << 20, 1),
        ] {
            let arena = Arena::<[u64; 2]>::with_chunk_bytes(hint, chunk_bytes);
            let refs: Vec<Vec<(u64, ArenaRef<[u64; 2]>)>> = std::thread::scope(|s| {
                let handles: Vec<_> = (0..4u64)
                    .map(|t| {
                        let arena = &arena;
                        s.spawn(move || {
                            let mut out = Vec::new();
                            let mut cursor = Cursor::empty();
                            for i in 0..1_000u64 {
                                if i % 100 == 0 {
                                    cursor = Cursor::empty();
                                }
                                let v = t * 1_000_000 + i;
                                // SAFETY: read below, before the arena is dropped; the
                                // cursor is this arena's.
                                out.push((v, unsafe { arena.push(&mut cursor, [v, !v]) }));
                            }
                            out
                        })
                    })
                    .collect();
                handles.into_iter().map(|h| h.join().unwrap()).collect()
            });
            let mut seen = 0;
            for (v, r) in refs.iter().flatten() {
                assert_eq!(**r, [*v, !*v]);
                seen += 1;
            }
            assert_eq!(seen, 4_000);
            assert_eq!(arena.chunk_count(), chunks, "hint {hint}");
        }
    }
}

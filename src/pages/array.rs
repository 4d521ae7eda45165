//! A growable array that, from [`MAPPED_MIN_BYTES`] up, lives in a mapping of its own
//! advised for transparent huge pages before its first touch.
//!
//! For the BVH's node and triangle-group arrays (`accel::bvhn`): a 10^6-triangle tree
//! is ~21 MB of nodes and ~40 MB of groups, ~15,000 4 KiB pages, and its traversals
//! miss the TLB on most node and group loads. Embree's allocator advises its blocks
//! before writing them, and its 10^6 process holds ~62 MiB of huge pages; without them
//! (`PR_SET_THP_DISABLE`) it lost 16-17 % on primary rays and 11-14 % on diffuse ones
//! (pk26, session 26). Advising our arrays where `malloc` put them did not get them
//! huge pages reliably: glibc serves a 40 MB block from the heap when freed arrays of
//! an earlier build left room there (then only the whole 2 MiB pages not yet backed
//! can become huge, and none of a recycled block's are), and maps it afresh otherwise
//! at an address 16 bytes past a page. A mapping of our own, 2 MiB-aligned and advised
//! while still untouched, is backed by huge pages from its first write on: a handful of
//! huge-page faults (each zeroing 2 MiB) instead of ~15,000 small ones, and no copy
//! afterwards (`MADV_COLLAPSE` of the finished arrays copied them: see the dead end in
//! `accel::bvhn::tree`).
//!
//! Measured (hp27, session 27, 2026-11-29, AVX-512, interleaved rounds, Mrays/s
//! medians of 5 passes; `nomap` is the same binary with the mapping switched off by an
//! environment variable, since removed, `base` the session's base /tmp/base27):
//! - 10^6, 1 thread (`stream_profile /tmp/m1e6.obj MODE W 5`, 6 rounds, load 1.0-1.2),
//!   min/median/max of the rounds: bvh8-stream diffuse base 3.66/3.83/4.09, nomap
//!   3.87/4.00/4.15, mapped 3.83/4.28/4.58; bvh8-packet primary base 25.36/26.42/29.45,
//!   nomap 25.38/25.85/26.78, mapped 26.59/27.56/28.20.
//! - 10^6, 2 threads (`bench --mesh /tmp/m1e6.obj --threads 2 --reps 5 --modes
//!   bvh8-packet,bvh8-stream`, 4 rounds, load 1.0-1.5, `cpu` 0.98-0.99): bvh8-packet
//!   primary base 54.28/55.53/59.05, nomap 54.02/54.92/59.28, mapped 59.75/60.52/61.76;
//!   bvh8-stream diffuse base 7.81/7.94/8.08, nomap 8.79/9.02/9.23, mapped 9.46/9.89/
//!   10.30; build ms (medians) base 192/191, nomap 199/200, mapped 181/182.
//! - The bunny at 1 thread (its node array's room, 8.9 MB, is mapped; its 2.9 MB of
//!   groups are not): `bench --threads 1 --reps 5`, 4 rounds against base, load ~1.3:
//!   bvh8-stream diffuse 6.22/6.50/6.65 -> 7.30/7.49/7.59, build 15.6 -> 14.2 ms. A 1
//!   MiB threshold (the bunny's groups, and its nodes at 2 threads, mapped too) measured
//!   level against 4 MiB at 1 and 2 threads (4 rounds each), so the threshold stayed.
//!
//! - With dropped mappings kept for the next vectors ([`KEPT`]; the figures above are
//!   without), against base, 10^6: `build_time 1000000 5 T`, 4 rounds, load 1.3-1.4,
//!   build ms medians 1 thread 328/349/332/335 -> 292/310/301/288, 2 threads 183/187/
//!   182/201 -> 180/196/187/183; `build_time 10000000 2 2`, two pairs (min/max) 2216/
//!   2259 and 2281/2297 against 2248/2369 and 2125/2436. `bench --mesh /tmp/m1e6.obj
//!   --threads 1 --reps 5 --modes bvh8-packet,bvh8-stream,bvh4-stream`, 4 rounds, load
//!   1.05-1.24: bvh8-stream diffuse 3.80/3.96/4.00 -> 4.26/4.37/4.77, bvh4-stream
//!   diffuse 3.59/3.79/3.94 -> 4.13/4.23/4.45, bvh8-packet primary 25.40/26.41/27.42 ->
//!   28.25/28.62/28.94, build ms 317.8 -> 275.7; `--threads 2 --modes
//!   bvh8-packet,bvh8-stream`, 3 rounds, load 0.96-1.23: primary 54.20/54.79/55.01 ->
//!   56.80/57.71/59.04, bvh8-stream diffuse 7.91/8.04/8.23 -> 8.88/9.04/9.10, build ms
//!   196/203 -> 192/174. Embree in the same window (`embree_bench /tmp/m1e6.obj
//!   --threads T --reps 5`, best mode, stream): diffuse 4.17 (1 thread), 8.35 (2),
//!   build 414 / 210 ms.
//!
//! Smaller arrays (and every array where the mapping fails, or off Linux) are ordinary
//! `Vec` buffers of the global allocator; [`LargeVec::from_vec`] also adopts a `Vec`
//! made elsewhere (the build's recycled reference memory, `accel::sah_build::SpareRefs`).

use std::mem::MaybeUninit;
use std::ptr::NonNull;

/// Arrays of at least this many bytes (capacity) get a huge-page mapping of their own:
/// two huge pages, as [`advise_huge_pages`](super::advise_huge_pages) asks; smaller ones
/// stay on the heap.
pub(crate) const MAPPED_MIN_BYTES: usize = 4 << 20;

/// The transparent huge page size (x86-64).
const HUGE: usize = 2 << 20;

/// A vector of `Copy` values (no drop glue to run) whose buffer is either a `Vec`'s
/// (freed as that `Vec` would be) or an anonymous mapping of its own, 2 MiB-aligned
/// and advised for huge pages before anything is written to it (unmapped on drop).
/// Reads go through `Deref<Target = [T]>`, so traversal code indexes it as a slice.
pub struct LargeVec<T: Copy> {
    ptr: NonNull<T>,
    len: usize,
    cap: usize,
    /// Bytes of the mapping that `ptr` starts (a multiple of 2 MiB), or 0 for a `Vec`'s
    /// buffer with capacity `cap`.
    mapped: usize,
}

// SAFETY: a `LargeVec<T>` owns its values as a `Vec<T>` does (the buffer is reached only
// through `&self` / `&mut self`), so it may move and be shared between threads exactly
// when `T` may.
unsafe impl<T: Copy + Send> Send for LargeVec<T> {}
// SAFETY: as above; `&LargeVec<T>` gives only `&[T]`.
unsafe impl<T: Copy + Sync> Sync for LargeVec<T> {}

impl<T: Copy> LargeVec<T> {
    const CHECK: () = assert!(
        std::mem::size_of::<T>() > 0 && std::mem::align_of::<T>() <= HUGE,
        "LargeVec holds sized values aligned to at most 2 MiB"
    );

    /// An empty vector without a buffer.
    pub fn new() -> Self {
        Self::from_vec(Vec::new())
    }

    /// Takes over `v`'s buffer (no copy); it stays a heap buffer.
    pub fn from_vec(v: Vec<T>) -> Self {
        let mut v = std::mem::ManuallyDrop::new(v);
        let (len, cap) = (v.len(), v.capacity());
        // A Vec's pointer is never null (dangling when it has no buffer).
        let ptr = NonNull::new(v.as_mut_ptr()).expect("a Vec's pointer is non-null");
        LargeVec {
            ptr,
            len,
            cap,
            mapped: 0,
        }
    }

    /// An empty vector with room for `cap` values: in a huge-page mapping of its own
    /// when that room is at least [`MAPPED_MIN_BYTES`], else on the heap.
    pub fn with_capacity(cap: usize) -> Self {
        let () = Self::CHECK;
        let bytes = cap
            .checked_mul(std::mem::size_of::<T>())
            .expect("array size overflows");
        if bytes >= MAPPED_MIN_BYTES
            && let Some((ptr, mapped)) = map_huge(bytes)
        {
            return LargeVec {
                ptr: ptr.cast(),
                len: 0,
                cap: mapped / std::mem::size_of::<T>(),
                mapped,
            };
        }
        Self::from_vec(Vec::with_capacity(cap))
    }

    /// Whether the buffer is a mapping of its own (advised for huge pages).
    pub fn is_mapped(&self) -> bool {
        self.mapped > 0
    }

    pub fn capacity(&self) -> usize {
        self.cap
    }

    /// Makes room for at least `additional` more values: a new buffer (by
    /// [`LargeVec::with_capacity`], at least double the old room) with the values
    /// copied, when they do not fit.
    pub fn reserve(&mut self, additional: usize) {
        let need = self.len.checked_add(additional).expect("capacity overflow");
        if need <= self.cap {
            return;
        }
        let mut grown = Self::with_capacity(need.max(2 * self.cap));
        grown.spare_capacity_mut()[..self.len].copy_from_slice(as_uninit(self));
        // SAFETY: the first `self.len` slots were just written.
        unsafe { grown.set_len(self.len) };
        *self = grown;
    }

    pub fn push(&mut self, value: T) {
        if self.len == self.cap {
            self.reserve(1);
        }
        // SAFETY: `len < cap` now, and the buffer has room for `cap` values.
        unsafe { self.ptr.as_ptr().add(self.len).write(value) };
        self.len += 1;
    }

    /// The room past the values (`capacity - len` slots).
    pub fn spare_capacity_mut(&mut self) -> &mut [MaybeUninit<T>] {
        // SAFETY: slots `len..cap` lie in the buffer, which this vector owns and
        // borrows mutably here; `MaybeUninit` needs no initialisation.
        unsafe {
            std::slice::from_raw_parts_mut(
                self.ptr.as_ptr().add(self.len).cast::<MaybeUninit<T>>(),
                self.cap - self.len,
            )
        }
    }

    /// # Safety
    /// `len <= capacity`, and the first `len` slots hold values (written through
    /// [`LargeVec::spare_capacity_mut`] or before).
    pub unsafe fn set_len(&mut self, len: usize) {
        debug_assert!(len <= self.cap);
        self.len = len;
    }

    /// `f` of each value, in a vector of the same kind: in place when `U` is as large
    /// as `T` (the identity map of exact BVH nodes), else in a new one.
    pub fn map<U: Copy>(self, f: impl Fn(&T) -> U) -> LargeVec<U> {
        let () = LargeVec::<U>::CHECK;
        if !self.is_mapped() {
            // The `Vec`'s own in-place collect where the layouts allow it.
            return LargeVec::from_vec(self.into_vec_buffer().into_iter().map(|x| f(&x)).collect());
        }
        if std::mem::size_of::<U>() != std::mem::size_of::<T>() {
            let mut out = LargeVec::with_capacity(self.len);
            for x in self.iter() {
                out.push(f(x));
            }
            return out;
        }
        let this = std::mem::ManuallyDrop::new(self);
        let (ptr, len, mapped) = (this.ptr.as_ptr(), this.len, this.mapped);
        for i in 0..len {
            // SAFETY: slot `i` holds a `T`, read before the `U` of the same size is
            // written over it; the mapping is 2 MiB-aligned, enough for `U`
            // (`CHECK`); slots other than `i` are not touched.
            unsafe {
                let x = ptr.add(i).read();
                ptr.add(i).cast::<U>().write(f(&x));
            }
        }
        LargeVec {
            // SAFETY: from a non-null pointer.
            ptr: unsafe { NonNull::new_unchecked(ptr.cast::<U>()) },
            len,
            cap: mapped / std::mem::size_of::<U>(),
            mapped,
        }
    }

    /// The heap buffer as the `Vec` it came from (only for `!is_mapped()`).
    fn into_vec_buffer(self) -> Vec<T> {
        debug_assert!(!self.is_mapped());
        let this = std::mem::ManuallyDrop::new(self);
        // SAFETY: pointer, length and capacity of a `Vec<T>` taken apart in
        // `from_vec` (or of one made by `map` from such parts), owned by `this`, which
        // is never dropped.
        unsafe { Vec::from_raw_parts(this.ptr.as_ptr(), this.len, this.cap) }
    }
}

impl<T: Copy> Default for LargeVec<T> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: Copy> Drop for LargeVec<T> {
    fn drop(&mut self) {
        if self.mapped == 0 {
            // SAFETY: a `Vec<T>`'s parts, as in `into_vec_buffer`; `T: Copy` has no
            // drop glue, so the values need nothing else.
            drop(unsafe { Vec::from_raw_parts(self.ptr.as_ptr(), self.len, self.cap) });
        } else {
            // The mapping made by `map_huge`, owned by this vector: kept or unmapped.
            #[cfg(target_os = "linux")]
            give_back(self.ptr.as_ptr().cast(), self.mapped);
        }
    }
}

impl<T: Copy> std::ops::Deref for LargeVec<T> {
    type Target = [T];
    #[inline(always)]
    fn deref(&self) -> &[T] {
        // SAFETY: the first `len` slots hold values; the pointer is non-null and
        // aligned (a `Vec`'s, or a 2 MiB-aligned mapping).
        unsafe { std::slice::from_raw_parts(self.ptr.as_ptr(), self.len) }
    }
}

impl<T: Copy> std::ops::DerefMut for LargeVec<T> {
    #[inline(always)]
    fn deref_mut(&mut self) -> &mut [T] {
        // SAFETY: as in `deref`, borrowed mutably through `&mut self`.
        unsafe { std::slice::from_raw_parts_mut(self.ptr.as_ptr(), self.len) }
    }
}

impl<'a, T: Copy> IntoIterator for &'a LargeVec<T> {
    type Item = &'a T;
    type IntoIter = std::slice::Iter<'a, T>;
    fn into_iter(self) -> Self::IntoIter {
        self.iter()
    }
}

impl<T: Copy + std::fmt::Debug> std::fmt::Debug for LargeVec<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.iter()).finish()
    }
}

/// The values as `MaybeUninit`s, for copying into spare room.
fn as_uninit<T: Copy>(s: &[T]) -> &[MaybeUninit<T>] {
    // SAFETY: `MaybeUninit<T>` has `T`'s layout, and an initialised value is a valid
    // `MaybeUninit`.
    unsafe { std::slice::from_raw_parts(s.as_ptr().cast(), s.len()) }
}

/// A fresh private anonymous mapping of `bytes` rounded up to 2 MiB, starting on a
/// 2 MiB boundary and advised for huge pages (`MADV_HUGEPAGE`; this host's
/// `transparent_hugepage` is `madvise`) before anything touches it: (start, length).
/// `None` where the mapping fails, and off Linux.
#[cfg(target_os = "linux")]
fn map_huge(bytes: usize) -> Option<(NonNull<u8>, usize)> {
    let len = bytes.checked_next_multiple_of(HUGE)?;
    if let Some(kept) = take_kept(len) {
        return Some(kept);
    }
    // One huge page of slack, so that a 2 MiB boundary lies in the first one.
    let over = len.checked_add(HUGE)?;
    // SAFETY: a new private anonymous mapping at an address of the kernel's choice
    // (`MAP_NORESERVE`: only the touched pages are ever backed).
    let p = unsafe {
        libc::mmap(
            std::ptr::null_mut(),
            over,
            libc::PROT_READ | libc::PROT_WRITE,
            libc::MAP_PRIVATE | libc::MAP_ANONYMOUS | libc::MAP_NORESERVE,
            -1,
            0,
        )
    };
    if p == libc::MAP_FAILED {
        return None;
    }
    let (p, start) = (p as usize, (p as usize).next_multiple_of(HUGE));
    // SAFETY: the slack before `start` and after `start + len` is part of the mapping
    // just made and holds nothing; unmapping it leaves exactly `[start, start + len)`.
    // MADV_HUGEPAGE on that untouched range only changes how its pages will be backed.
    unsafe {
        if start > p {
            libc::munmap(p as *mut libc::c_void, start - p);
        }
        if p + over > start + len {
            libc::munmap((start + len) as *mut libc::c_void, p + over - start - len);
        }
        libc::madvise(start as *mut libc::c_void, len, libc::MADV_HUGEPAGE);
    }
    Some((NonNull::new(start as *mut u8)?, len))
}

/// Mappings of dropped vectors kept for the next ones, at most [`KEEP`]: (start,
/// length). A build's tree arrays are dropped when the next build of the same mesh
/// (a benchmark's repetitions, a scene rebuilt per frame) needs the same sizes again;
/// a kept mapping's pages are already backed (by huge pages), so the next tree is
/// written without page faults, as the builder's own arrays are when glibc recycles
/// them from its heap. Fresh huge pages are cheap on a quiet host but cost a host
/// fault each when the VM's free memory was reported to the host (see
/// `advise_huge_pages`): `build_time 1000000 5 1` without keeping, 4 runs at load 0.5,
/// build ms min/median/max 333.9/472.6/477.3 and 319.5/457.4/511.7 against the base's
/// 324.1/329.7/363.0 and 317.8/322.4/345.5 (with the tree's arrays from glibc).
#[cfg(target_os = "linux")]
static KEPT: std::sync::Mutex<Vec<(usize, usize)>> = std::sync::Mutex::new(Vec::new());

/// How many dropped mappings [`KEPT`] holds: a tree's two arrays, for two trees (a
/// benchmark's BVH8 and BVH4 alternating), and the 16 MiB chunks of a build's child
/// pairs (`accel::build_arena`: 16 at 10^7 triangles, 256 MiB, which with the 10^7
/// tree's node mapping stays under [`KEEP_BYTES`]). It was 4 before the chunks were
/// kept (issue 12, helper bc28, session 28).
#[cfg(target_os = "linux")]
const KEEP: usize = 24;

/// The most bytes [`KEPT`] holds, resident after their trees are gone: a 10^7-triangle
/// tree's node mapping (~210 MB) and two 10^6 trees' arrays (~61 MB each) fit; a library
/// user who drops larger trees gets the rest of their memory back. Measured (session 27,
/// AVX-512, `build_time 10000000 2 2`, 3 interleaved rounds, wall ms medians): with a
/// 192 MiB cap (the 10^7 node mapping unmapped on drop) 2,159 / 2,065 / 2,085 against
/// 1,948 / 1,844 / 2,061 with the mapping kept.
#[cfg(target_os = "linux")]
const KEEP_BYTES: usize = 512 << 20;

/// The smallest kept mapping of at least `len` bytes, taken out of [`KEPT`].
#[cfg(target_os = "linux")]
fn take_kept(len: usize) -> Option<(NonNull<u8>, usize)> {
    let mut kept = KEPT.lock().unwrap_or_else(|e| e.into_inner());
    let i = (0..kept.len())
        .filter(|&i| kept[i].1 >= len)
        .min_by_key(|&i| kept[i].1)?;
    let (start, mapped) = kept.swap_remove(i);
    Some((NonNull::new(start as *mut u8)?, mapped))
}

/// Keeps the mapping `[start, start + mapped)` for a later vector, or unmaps it where
/// [`KEEP`] are kept already or it would take the kept bytes past [`KEEP_BYTES`].
#[cfg(target_os = "linux")]
fn give_back(start: *mut u8, mapped: usize) {
    let mut kept = KEPT.lock().unwrap_or_else(|e| e.into_inner());
    let held: usize = kept.iter().map(|k| k.1).sum();
    if kept.len() < KEEP && held + mapped <= KEEP_BYTES {
        kept.push((start as usize, mapped));
        return;
    }
    drop(kept);
    // SAFETY: a mapping made by `map_huge`, no longer used by any vector, unmapped once.
    unsafe {
        libc::munmap(start.cast(), mapped);
    }
}

#[cfg(not(target_os = "linux"))]
fn map_huge(_bytes: usize) -> Option<(NonNull<u8>, usize)> {
    None
}

#[cfg(all(test, target_os = "linux"))]
mod tests {
    use super::*;
    use crate::pages::vm_flags_at;

    /// A large array gets a 2 MiB-aligned mapping advised for huge pages (`hg`), and
    /// its values are what was pushed; a small one stays on the heap; both survive
    /// growth and the in-place map.
    #[test]
    fn large_arrays_get_an_advised_mapping_small_ones_the_heap() {
        let n = (9 << 20) / 16;
        let mut large = LargeVec::<[u32; 4]>::with_capacity(n);
        assert!(large.is_mapped());
        assert_eq!(large.as_ptr() as usize % HUGE, 0, "2 MiB-aligned");
        assert!(large.capacity() >= n);
        for i in 0..n as u32 {
            large.push([i, i + 1, i + 2, i + 3]);
        }
        let flags = vm_flags_at(large.as_ptr() as usize).expect("the mapping in smaps");
        assert!(flags.iter().any(|f| f == "hg"), "not advised: {flags:?}");
        let doubled = large.map(|v| [v[0] * 2, v[1], v[2], v[3]]);
        assert!(doubled.is_mapped());
        assert_eq!(doubled.len(), n);
        for (i, v) in doubled.iter().enumerate() {
            let i = i as u32;
            assert_eq!(*v, [2 * i, i + 1, i + 2, i + 3]);
        }
        let halves = doubled.map(|v| v[0] as u64);
        assert_eq!(halves.len(), n);
        assert!(halves.iter().enumerate().all(|(i, &v)| v == 2 * i as u64));

        let mut small = LargeVec::<u32>::with_capacity(1000);
        assert!(!small.is_mapped());
        for i in 0..5000 {
            small.push(i);
        }
        assert!(small.iter().copied().eq(0..5000));
        // Growing past 4 MiB moves the values into a mapping.
        small.reserve(2 << 20);
        assert!(small.is_mapped());
        assert!(small.iter().copied().eq(0..5000));
        let flags = vm_flags_at(small.as_ptr() as usize).expect("mapping");
        assert!(flags.iter().any(|f| f == "hg"), "not advised: {flags:?}");
        let v = LargeVec::from_vec(vec![1u8, 2, 3]);
        assert!(!v.is_mapped());
        assert_eq!(&v[..], &[1, 2, 3]);
        assert_eq!(&v.map(|&x| x as u32 + 1)[..], &[2, 3, 4]);
    }
}

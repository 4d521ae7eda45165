//! Transparent huge pages for large arrays written soon after they are made.
//!
//! The BVH builder's reference arrays (`accel::sah_build`) and the film
//! (`film::Film::new`) ask for them; the choice, and the host states in which it was
//! measured both ways, are recorded on [`advise_huge_pages`].

/// Blocks at least this large are mapped afresh by glibc's `malloc` and unmapped by
/// `free` (its largest mmap threshold, `DEFAULT_MMAP_THRESHOLD_MAX`, 32 MiB on 64-bit);
/// smaller ones may come from the heap and share their first and last page.
pub(crate) const ALWAYS_MAPPED_BYTES: usize = 32 << 20;

/// Asks the kernel to back the whole 2 MiB pages inside `[ptr, ptr + len)` with huge
/// pages (`madvise(MADV_HUGEPAGE)`; the machine's `transparent_hugepage` setting is
/// `madvise`). Only for arrays of at least 4 MiB; failure changes nothing but speed.
///
/// An array that may be recycled (at least [`ALWAYS_MAPPED_BYTES`]: a mapped block of
/// its own) is advised over every 4 KiB page it touches, not only its whole 2 MiB
/// pages (only those get huge pages either way): advice on part of a mapping splits
/// it in several, and `mremap` refuses a range across mappings (`EFAULT`), so glibc's
/// `realloc` of the array (`accel::sah_build::SpareRefs::into_vec`) then copied all of it into a fresh
/// block (seen with `strace` at 10^7: 320 MB copied, 419 MB of fresh pages). Smaller
/// arrays, heap blocks that may share their first and last page, keep the advice to
/// their whole huge pages.
///
/// Dead end (issue 12, helper bld23, 2026-11-29, commit ea0c063, reverted by the lead the
/// same day): no advice for arrays of [`ALWAYS_MAPPED_BYTES`] and more. bld23's reasoning
/// and its loaded measurements, as it wrote them:
///
/// "Not for larger arrays, which glibc maps afresh for every build and unmaps after
/// (issue 12, helper bld23, 2026-11-29). This VM's balloon reports free memory to the
/// host in blocks of 2 MiB and more (virtio-balloon `F_REPORTING`,
/// `page_reporting_order` 9), and the host takes those pages back; a huge page is
/// such a block, so touching a fresh one costs a host fault besides the guest's
/// zeroing, while 4 KiB pages come first from smaller free blocks, never reported. A C
/// test (`mmap` of 320 MB, one write per 4 KiB, unmapped, alternating 4 KiB and huge
/// pages; load ~3): with 3 s between rounds, 4 KiB pages 208-323 ms and huge pages
/// 1,367-1,788 ms; back to back, 214-239 against 82-109 ms (the first huge round
/// 1,718). perf of `build_time 10000000 1 1` (two builds, 4 kHz `cpu-clock`), samples
/// under page faults by the faulting function: with the advice 6,337 in
/// `partition_on_axis` (the root's partition into the fresh scratch array), 4,241
/// making the references, 1,113 the collapse's nodes, 864 `sysmalloc` (the child
/// pairs' heap), 166 the triangle groups, 12,927 in all; without it 1,196 / 1,177 /
/// 859 / 2,548 / 1,364, 7,722 in all (the later arrays now get more of the reported
/// blocks, but the build pays ~650 ms less per build). CPU ms per 10^7 build
/// (`build_time 10000000 2 1`, medians of 2, interleaved with the build before, load
/// 4.8-8.8 with compiles running): 6,651 / 5,467 / 5,221 before against 4,556 / 4,670 /
/// 3,861; with the 48-byte [`BuildNode`] too (load 4.3-5.2), 4,670 / 4,585 / 3,905
/// against 4,051 / 3,977 / 3,834, wall ms 13,689 / 6,496 / 3,950 against 10,791 /
/// 5,765 / 3,767 (2.65 Mtriangles/s in the quietest round). Page faults per build
/// 69,058 -> 247,396 (4 KiB each now). On a host without free-page reporting the
/// advice would win instead (the back-to-back rounds above). Before, an advised array
/// larger than this was advised over every page it touched, so that `mremap` could
/// still move it whole (`accel::sah_build::SpareRefs::into_vec`); unadvised it needs no care."
///
/// On a quiet host (load 0.9-1.5, 04:44-04:47 UTC) the advice wins: `build_time
/// 10000000 2 1` interleaved with the session's starting build, 5 rounds (the order
/// swapped in the last two), wall ms medians of the starting build (the advice, 64-byte
/// `BuildNode`s) 3,462 / 3,610 / 3,361 / 3,521 / 3,486 against 3,563 / 3,792 / 3,816 /
/// 3,880 / 3,860 for bld23's (no advice above 32 MiB, 48-byte nodes, the latter within
/// the noise on its own): slower in every round, 2.62 against 2.87 Mtriangles/s at the
/// median. Which side wins depends on
/// whether the host is reclaiming reported pages at the time; the quiet figure is the
/// one the project quotes, so the advice stays.
///
/// The film (session 26, 2026-11-29, the host in its slow state, load ~1): fresh 4 KiB
/// pages cost 5-40 us each to touch (a C loop over fresh 12 MB mappings, one write per
/// page: 49-122 ms), huge pages 2-8 ms for the same 12 MB (one round 33 ms); the guest
/// had 22 GB free, mostly in order-10 blocks, so no compaction was needed. The earlier
/// dead end on the film (46-120 ms in half the runs, direct compaction, load 7.5 with
/// builds running) was a fragmented guest. Frames with the film advised, 12 interleaved
/// rounds each, 1 thread, min/median/max ms: whitted_base 1024x768 render 68.4/77.1/
/// 167.6 -> 60.2/63.5/83.8 (film stage 13.2/18.1/90.0 -> 3.9/6.5/24.6), bunny 1024x1024
/// 66.3/70.3/79.2 -> 53.7/59.0/84.4 (film 15.2/19.0/26.0 -> 4.8/8.2/32.4).
pub(crate) fn advise_huge_pages(ptr: *mut u8, len: usize) {
    #[cfg(target_os = "linux")]
    {
        const HUGE: usize = 2 << 20;
        const PAGE: usize = 4 << 10;
        if len < 2 * HUGE {
            return;
        }
        let (first, last) = (ptr as usize, ptr as usize + len);
        let (start, end) = if len >= ALWAYS_MAPPED_BYTES {
            (first / PAGE * PAGE, last.next_multiple_of(PAGE))
        } else {
            (first.next_multiple_of(HUGE), last / HUGE * HUGE)
        };
        if end > start {
            // SAFETY: the range is (at most) the pages the live allocation lies in;
            // MADV_HUGEPAGE only changes how pages are backed, never their contents, so
            // it leaves anything else on the first and last page as it was.
            unsafe {
                libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
            }
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (ptr, len);
}

/// The `VmFlags` of the mapping that holds `addr` (`/proc/self/smaps`), for tests.
#[cfg(all(test, target_os = "linux"))]
pub(crate) fn vm_flags_at(addr: usize) -> Option<Vec<String>> {
    let smaps = std::fs::read_to_string("/proc/self/smaps").ok()?;
    let mut inside = false;
    for line in smaps.lines() {
        let first = line.split_whitespace().next().unwrap_or("");
        if let Some((lo, hi)) = first.split_once('-')
            && let (Ok(lo), Ok(hi)) = (usize::from_str_radix(lo, 16), usize::from_str_radix(hi, 16))
        {
            inside = (lo..hi).contains(&addr);
        } else if inside && let Some(flags) = line.strip_prefix("VmFlags:") {
            return Some(flags.split_whitespace().map(str::to_string).collect());
        }
    }
    None
}

#[cfg(all(test, target_os = "linux"))]
mod tests {
    use super::*;

    /// A fresh anonymous mapping of `len` bytes of its own (unmapped on drop): a heap
    /// block may share a mapping that another test advised earlier, whose `hg` flag
    /// outlives the block.
    struct Mapping(*mut u8, usize);

    impl Mapping {
        fn new(len: usize) -> Mapping {
            // SAFETY: a private anonymous mapping at an address of the kernel's choice.
            let p = unsafe {
                libc::mmap(
                    std::ptr::null_mut(),
                    len,
                    libc::PROT_READ | libc::PROT_WRITE,
                    libc::MAP_PRIVATE | libc::MAP_ANONYMOUS,
                    -1,
                    0,
                )
            };
            assert_ne!(p, libc::MAP_FAILED, "mmap of {len} bytes");
            Mapping(p.cast(), len)
        }
    }

    impl Drop for Mapping {
        fn drop(&mut self) {
            // SAFETY: the mapping made in `new`, unmapped once.
            unsafe { libc::munmap(self.0.cast(), self.1) };
        }
    }

    /// A large array's whole 2 MiB pages are advised (`hg` in the mapping's flags); an
    /// array under 4 MiB is left alone.
    #[test]
    fn large_arrays_are_advised_small_ones_are_not() {
        const HUGE: usize = 2 << 20;
        let (large, small) = (Mapping::new(9 << 20), Mapping::new(3 << 20));
        advise_huge_pages(large.0, large.1);
        advise_huge_pages(small.0, small.1);
        let inner = (large.0 as usize).next_multiple_of(HUGE);
        let flags = vm_flags_at(inner).expect("the large array's mapping in smaps");
        assert!(
            flags.iter().any(|f| f == "hg"),
            "large array not advised: {flags:?}"
        );
        let flags = vm_flags_at(small.0 as usize + (1 << 20)).expect("small mapping");
        assert!(
            !flags.iter().any(|f| f == "hg"),
            "small array advised: {flags:?}"
        );
    }
}

//! Mapping a span of fresh memory in one call before it is written.
//!
//! The film comes from `alloc_zeroed` (zero pages from the kernel, see
//! [`Film::new`](crate::film::Film::new)), so each 4 KiB page of it is mapped by a page fault
//! when the tile renderer first writes it: 3,072 faults for the bunny's 12 MB frame,
//! 2,304 for a 1024x768 one. On this VM a fault costs 1.3-4.3 us, and the bunny frame's
//! `resolve` stage (the tile-to-film copy, where those faults land) was 6.8-10.0 ms of
//! a 66-98 ms render phase. `madvise(MADV_POPULATE_WRITE)` maps a whole band of rows in
//! one call: the same page allocation and zeroing, without one trap per page (the
//! process's minor-fault count is the same: 11,037-11,042 before, 11,011-11,018 after).
//! Measured on this host with a C loop over fresh 12 MB mappings written band by band
//! (196,608-byte bands, the bunny's 16 rows), 20 interleaved rounds each, 3 runs at load
//! ~6, min/median ms: `memset` per band 5.3/10.8, 6.6/15.1, 9.7/14.6; populate then
//! `memset` per band 3.2/7.4, 3.6/8.9, 3.6/8.8. Pages the process had just freed were no
//! cheaper to touch (1.3-2.9 us a page), so the cost is the guest kernel's fault path,
//! not the hypervisor's first touch. Bunny 1024x1024, 1 thread, three sets of 8-9
//! interleaved rounds against the build before (load 6-7, where whole frames varied
//! 100-200 ms), `resolve` min/median: 10.8/13.1 -> 5.4/9.9, 7.0/14.2 -> 5.6/7.0, 7.0/13.5
//! -> 6.5/14.5 ms; the render phase did not move outside that noise.
//!
//! Called per band of rows by the thread that renders it, so at 2 threads the bands are
//! mapped in parallel. Since session 26 the film is advised for huge pages first
//! (`pages::advise_huge_pages`): a band then maps the whole 2 MiB pages it lies in.
//! The dead end in `Film::new` was one call for the whole frame before any tile
//! (serial, 16-28 ms at load 7.5).

/// Asks the kernel to map every page that `span` touches as if written, so that the
/// writes that follow take no page fault. Contents are unchanged (the kernel only
/// allocates what is not yet mapped, zero-filled as a write fault would). Returns
/// whether the call succeeded: `false` on kernels before Linux 5.14, on other systems,
/// for an empty span, and when the memory cannot be had, where nothing is done and
/// the writes fault as before.
pub(crate) fn populate_for_writing<T>(span: &mut [T]) -> bool {
    matches!(commit_for_writing(span), Ok(true))
}

/// [`populate_for_writing`] that tells why it did nothing: `Ok(true)` when every page
/// is mapped now, `Ok(false)` where the system cannot map ahead (kernels before Linux
/// 5.14 answer `EINVAL`, other systems have no such call, an empty span has no
/// pages), and the error where the kernel could not give the memory (`ENOMEM`): a
/// caller that commits memory before any work can refuse the work then.
pub(crate) fn commit_for_writing<T>(span: &mut [T]) -> std::io::Result<bool> {
    let bytes = std::mem::size_of_val(span);
    if bytes == 0 {
        return Ok(false);
    }
    populate(span.as_mut_ptr().cast(), bytes)
}

#[cfg(target_os = "linux")]
fn populate(start: *mut u8, bytes: usize) -> std::io::Result<bool> {
    // SAFETY: `sysconf` has no preconditions.
    let page = match unsafe { libc::sysconf(libc::_SC_PAGESIZE) } {
        p if p > 0 => p as usize,
        _ => return Ok(false),
    };
    // The pages `start..start + bytes` lies in: the first and last may be shared with
    // neighbouring memory of the same mapping, which is already mapped or is mapped
    // now, unchanged.
    let first = start as usize & !(page - 1);
    let end = (start as usize + bytes).next_multiple_of(page);
    // SAFETY: MADV_POPULATE_WRITE changes no byte of memory (it maps pages the way a
    // write fault would, zero-filled or as they are), and the range lies in pages of
    // the mapping that holds `span`; on a range it cannot populate it fails with an
    // error and does nothing harmful.
    let rc = unsafe {
        libc::madvise(
            first as *mut libc::c_void,
            end - first,
            libc::MADV_POPULATE_WRITE,
        )
    };
    if rc == 0 {
        return Ok(true);
    }
    let err = std::io::Error::last_os_error();
    match err.raw_os_error() {
        Some(libc::EINVAL) | Some(libc::ENOSYS) => Ok(false),
        _ => Err(err),
    }
}

#[cfg(not(target_os = "linux"))]
fn populate(_start: *mut u8, _bytes: usize) -> std::io::Result<bool> {
    Ok(false)
}

#[cfg(all(test, target_os = "linux"))]
mod tests {
    use super::*;

    /// Which of the `pages` pages from `base` are resident (`mincore`).
    fn resident(base: *mut u8, pages: usize, page: usize) -> Vec<bool> {
        let mut vec = vec![0u8; pages];
        // SAFETY: `base..base + pages * page` is one mapping made by the test.
        let rc = unsafe { libc::mincore(base.cast(), pages * page, vec.as_mut_ptr()) };
        assert_eq!(rc, 0, "mincore");
        vec.iter().map(|v| v & 1 == 1).collect()
    }

    /// A span in the middle of a fresh anonymous mapping, not page-aligned at either
    /// end: before the call none of its pages is resident; after it every page the
    /// span touches is, the pages outside it are not, and every byte is what it was
    /// (zero inside; the bytes written first by hand kept).
    #[test]
    fn populate_maps_the_spans_pages_and_keeps_their_bytes() {
        // SAFETY: `sysconf` has no preconditions.
        let page = unsafe { libc::sysconf(libc::_SC_PAGESIZE) } as usize;
        let pages = 16;
        // SAFETY: a fresh private anonymous mapping, unmapped at the end.
        let base = unsafe {
            libc::mmap(
                std::ptr::null_mut(),
                pages * page,
                libc::PROT_READ | libc::PROT_WRITE,
                libc::MAP_PRIVATE | libc::MAP_ANONYMOUS,
                -1,
                0,
            )
        };
        assert_ne!(base, libc::MAP_FAILED);
        let base = base.cast::<u8>();
        assert!(resident(base, pages, page).iter().all(|r| !r));
        // Page 3 written by hand before: its bytes must survive.
        // SAFETY: inside the mapping.
        unsafe { base.add(3 * page + 100).write(7) };
        // From the middle of page 3 to the middle of page 9.
        let (from, to) = (3 * page + 40, 9 * page + 200);
        // SAFETY: inside the mapping, u8 has no invalid values.
        let span = unsafe { std::slice::from_raw_parts_mut(base.add(from), to - from) };
        let committed = commit_for_writing(span);
        if let Ok(false) = committed {
            // Kernels before Linux 5.14 reject the advice with EINVAL: the renderer
            // then takes the page faults as before, and there is nothing to check.
            // SAFETY: the mapping made above.
            unsafe { libc::munmap(base.cast(), pages * page) };
            eprintln!("skipped: this kernel has no MADV_POPULATE_WRITE");
            return;
        }
        assert!(committed.expect("madvise"), "span mapped");
        let now = resident(base, pages, page);
        for (p, r) in now.iter().enumerate() {
            assert_eq!(*r, (3..=9).contains(&p), "page {p}");
        }
        // SAFETY: the whole mapping is readable.
        let all = unsafe { std::slice::from_raw_parts(base, pages * page) };
        for (i, &b) in all.iter().enumerate() {
            assert_eq!(b, if i == 3 * page + 100 { 7 } else { 0 }, "byte {i}");
        }
        // SAFETY: the mapping made above.
        unsafe { libc::munmap(base.cast(), pages * page) };
        let mut empty: [u32; 0] = [];
        assert!(!populate_for_writing(&mut empty));
        assert!(!commit_for_writing(&mut empty).expect("nothing to map"));
    }
}

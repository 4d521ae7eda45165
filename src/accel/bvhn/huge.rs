//! Transparent huge pages for the node and leaf arrays of a large tree.
//!
//! Why (issue 12, pk17): at 10^6 triangles the BVH8 is ~60 MiB of nodes and triangle
//! groups in 4 KiB pages, about 15,000 pages against a second-level TLB that maps a
//! few MiB, so a packet's visits to the bottom levels, each on a page of its own, pay a
//! page walk on top of the cache miss. `perf annotate` of `examples/stream_profile
//! m1e6.obj bvh8-packet primary 12` (AVX-512, 1 thread, cpu-clock samples: the host
//! has no hardware counters) put 27 % of `packet_closest`'s samples on the first load
//! of a leaf group and 20 % on the first load of a node's planes; on the bunny (4 MiB)
//! neither stands out. Embree's allocator asks for the same (`os_advise`:
//! `madvise(MADV_HUGEPAGE)` on every block it maps). The host's
//! `transparent_hugepage` setting is `madvise`, so without the advice every page is
//! 4 KiB. Measured, it is no clear win: 10^6 primary, `stream_profile /tmp/m1e6.obj
//! MODE primary 7`, AVX-512, 1 thread, Mrays per CPU-second of interleaved runs on a
//! host at load 6-7 (`cpu` 0.17-0.67): without packet prefetch 12.06 / 12.59 with the
//! advice against 11.88 / 15.38 / 11.44 / 13.19 / 12.99 without; with it 15.18 / 15.12
//! against 14.44 / 14.65. Kept because it costs nothing measurable and Embree does it;
//! the cause of the first-load stalls is latency the packet prefetch hides
//! (`Prefetch::default`), not the TLB.

/// Arrays smaller than this stay as they are (a 4 MiB array fits the TLB's reach).
const MIN_BYTES: usize = 4 << 20;

/// Asks the kernel to back the whole 2 MiB pages inside `v`'s allocated capacity with
/// huge pages. Call it before the pages are first written (the advice applies at the
/// first fault; pages already present stay 4 KiB). Failure changes nothing but speed.
pub(super) fn advise_huge<T>(v: &Vec<T>) {
    let len = v.capacity() * std::mem::size_of::<T>();
    #[cfg(target_os = "linux")]
    {
        const HUGE: usize = 2 << 20;
        if len < MIN_BYTES {
            return;
        }
        let ptr = v.as_ptr() as usize;
        let start = ptr.next_multiple_of(HUGE);
        let end = (ptr + len) / HUGE * HUGE;
        if end > start {
            // SAFETY: the range lies inside `v`'s live allocation; MADV_HUGEPAGE only
            // changes how its pages are backed, never their contents.
            unsafe {
                libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
            }
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = len;
}

/// How many of the pages of `v`'s elements are huge pages, as `(huge KiB, total KiB)`
/// of the mappings they lie in (`/proc/self/smaps`), for the test that checks the
/// advice took; `None` where that file cannot be read.
#[cfg(test)]
pub(super) fn huge_kib<T>(v: &[T]) -> Option<(usize, usize)> {
    let text = std::fs::read_to_string("/proc/self/smaps").ok()?;
    let (lo, hi) = (
        v.as_ptr() as usize,
        v.as_ptr() as usize + std::mem::size_of_val(v),
    );
    let (mut huge, mut total, mut inside) = (0, 0, false);
    for line in text.lines() {
        let first = line.split_whitespace().next().unwrap_or("");
        if let Some((a, b)) = first.split_once('-')
            && let (Ok(a), Ok(b)) = (usize::from_str_radix(a, 16), usize::from_str_radix(b, 16))
        {
            inside = a < hi && b > lo;
            continue;
        }
        if !inside {
            continue;
        }
        let kib = |l: &str| {
            l.split_whitespace()
                .nth(1)
                .and_then(|x| x.parse::<usize>().ok())
                .unwrap_or(0)
        };
        if line.starts_with("AnonHugePages:") {
            huge += kib(line);
        } else if line.starts_with("Rss:") {
            total += kib(line);
        }
    }
    Some((huge, total))
}

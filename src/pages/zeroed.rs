//! Arrays of zeros that write nothing to become zero: the allocator's zeroed block
//! (fresh pages from the kernel for a large one), advised for huge pages before the
//! first touch ([`super::advise_huge_pages`]). The film, the builder's reference
//! arrays and its index array are made so.

use super::advise_huge_pages;
use std::alloc::Layout;

/// `n` values of all-zero bytes, or the layout the allocator refused (for a caller
/// that reports it instead of aborting).
///
/// # Safety
/// All-zero bytes must be a valid `T`.
pub(crate) unsafe fn try_zeroed_vec<T>(n: usize) -> Result<Vec<T>, Layout> {
    const { assert!(size_of::<T>() > 0, "no zero-sized values") };
    if n == 0 {
        return Ok(Vec::new());
    }
    // An impossible size is a bug in the caller, as for `Vec`, not a refusal.
    let layout = Layout::array::<T>(n).expect("array size overflows");
    // SAFETY: `layout` has a non-zero size (n > 0, T not zero-sized).
    let ptr = unsafe { std::alloc::alloc_zeroed(layout) }.cast::<T>();
    if ptr.is_null() {
        return Err(layout);
    }
    advise_huge_pages(ptr.cast(), layout.size());
    // SAFETY: allocated by the global allocator with the layout of `n` values of `T`
    // (the layout a `Vec<T>` of capacity `n` frees with), every byte zero, and all-zero
    // bytes are a valid `T` (the caller's promise).
    Ok(unsafe { Vec::from_raw_parts(ptr, n, n) })
}

/// [`try_zeroed_vec`], aborting where the memory cannot be had (as `Vec` does).
///
/// # Safety
/// All-zero bytes must be a valid `T`.
pub(crate) unsafe fn zeroed_vec<T>(n: usize) -> Vec<T> {
    // SAFETY: the caller's promise, passed on.
    unsafe { try_zeroed_vec(n) }.unwrap_or_else(|layout| std::alloc::handle_alloc_error(layout))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Zeros of every size class (empty, heap, a mapping of its own), a `Vec` of the
    /// global allocator that grows and frees as one; an impossible size is refused
    /// with a layout, not an abort.
    #[test]
    fn zeroed_arrays_are_zero_and_ordinary_vecs() {
        for n in [0, 1, 1000, (4 << 20) / 4 + 3, (40 << 20) / 4 + 5] {
            // SAFETY: all-zero bytes are a valid u32.
            let mut v: Vec<u32> = unsafe { zeroed_vec(n) };
            assert_eq!((v.len(), v.capacity()), (n, n));
            assert!(v.iter().all(|&x| x == 0), "{n}");
            v.push(7);
            assert_eq!(v[n], 7);
        }
        // SAFETY: all-zero bytes are a valid u64.
        let refused = unsafe { try_zeroed_vec::<u64>(usize::MAX / 16) };
        assert!(refused.is_err());
    }
}

//! The unit tests' random inputs: Marsaglia's xorshift64 ("Xorshift RNGs", 2003), one
//! generator instead of the same three shifts written in every test that needs numbers.

/// A xorshift64 stream from `state` (which must not be 0): each call returns the next
/// state.
pub(crate) fn xorshift64(mut state: u64) -> impl FnMut() -> u64 {
    move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    }
}

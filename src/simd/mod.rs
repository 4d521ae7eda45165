//! SIMD lane types (filled by the SIMD-core work).

//! How the renderer's large arrays get their memory: huge-page advice before the first
//! touch, zeroed arrays that write nothing, mappings of their own for the BVH's arrays ([`LargeVec`]), and mapping a span
//! in one call before it is written.

mod array;
mod huge;
mod populate;
mod zeroed;

pub use array::LargeVec;
#[cfg(test)]
pub(crate) use array::MAPPED_MIN_BYTES;
#[cfg(all(test, target_os = "linux"))]
pub(crate) use huge::vm_flags_at;
pub(crate) use huge::{ALWAYS_MAPPED_BYTES, advise_huge_pages};
pub(crate) use populate::{commit_for_writing, populate_for_writing};
pub(crate) use zeroed::{try_zeroed_vec, zeroed_vec};

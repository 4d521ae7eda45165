//! Procedural scene generators.

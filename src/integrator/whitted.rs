//! Recursive Whitted-style ray tracer (scalar reference).

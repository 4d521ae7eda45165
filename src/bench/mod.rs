//! The throughput protocol of shared/BENCHMARK.md.

//! Benchmark (filled in next).

//! dkrrt-rt: real-time utilities shared by every process: absolute-deadline
//! pacing, scheduling setup, latency histograms, and a counting allocator for
//! allocation tests.

pub mod alloc_count;

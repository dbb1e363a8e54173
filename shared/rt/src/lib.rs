//! dkrrt-rt: real-time utilities shared by every process: absolute-deadline
//! pacing on CLOCK_MONOTONIC, optional SCHED_FIFO / mlockall / CPU pinning,
//! SIGINT/SIGTERM handling, preallocated latency histograms, and a counting
//! allocator for allocation tests.

pub mod alloc_count;
pub mod clock;
pub mod hist;
pub mod rtsetup;
pub mod signals;

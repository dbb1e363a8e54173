//! dkrrt-rt: real-time utilities shared by every process: absolute-deadline
//! pacing on CLOCK_MONOTONIC, optional SCHED_FIFO / mlockall / CPU pinning,
//! SIGINT/SIGTERM handling, preallocated latency histograms, and a counting
//! allocator for allocation tests, and socket waits with sub-ms timeouts.

pub mod alloc_count;
pub mod clock;
pub mod hist;
pub mod poll;
pub mod rtsetup;
pub mod signals;

/// Writes a process's exit statistics as pretty JSON (`who` names it in errors).
pub fn write_stats<T: serde::Serialize>(
    who: &str,
    path: Option<&std::path::Path>,
    stats: &T,
) -> Result<(), String> {
    let Some(p) = path else { return Ok(()) };
    let text = serde_json::to_string_pretty(stats).map_err(|e| format!("{who}: {e}"))?;
    std::fs::write(p, text).map_err(|e| format!("{who}: write {}: {e}", p.display()))
}

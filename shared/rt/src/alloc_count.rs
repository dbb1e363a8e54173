//! A counting global allocator for allocation tests.
//!
//! Install it in a test binary:
//!
//! ```ignore
//! #[global_allocator]
//! static ALLOC: dkrrt_rt::alloc_count::CountingAlloc = dkrrt_rt::alloc_count::CountingAlloc;
//! ```
//!
//! then measure a region with [`count`]. Counts are per thread, so the test
//! harness's other threads do not disturb a measurement.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

/// Global allocator that forwards to [`System`] and counts, per thread,
/// allocations, deallocations, reallocations and bytes requested.
pub struct CountingAlloc;

thread_local! {
    static ALLOCS: Cell<u64> = const { Cell::new(0) };
    static DEALLOCS: Cell<u64> = const { Cell::new(0) };
    static REALLOCS: Cell<u64> = const { Cell::new(0) };
    static BYTES: Cell<u64> = const { Cell::new(0) };
}

fn bump(c: &'static std::thread::LocalKey<Cell<u64>>, by: u64) {
    // `try_with`: the thread-local may already be destroyed at thread exit.
    let _ = c.try_with(|v| v.set(v.get().wrapping_add(by)));
}

unsafe impl GlobalAlloc for CountingAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        bump(&ALLOCS, 1);
        bump(&BYTES, layout.size() as u64);
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        bump(&ALLOCS, 1);
        bump(&BYTES, layout.size() as u64);
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        bump(&DEALLOCS, 1);
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        bump(&REALLOCS, 1);
        bump(&BYTES, new_size as u64);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

/// What the current thread allocated during a measured region.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct AllocStats {
    pub allocs: u64,
    pub deallocs: u64,
    pub reallocs: u64,
    pub bytes: u64,
}

impl AllocStats {
    /// Snapshot of this thread's counters (only meaningful with [`CountingAlloc`] installed).
    pub fn now() -> Self {
        let g = |c: &'static std::thread::LocalKey<Cell<u64>>| c.try_with(|v| v.get()).unwrap_or(0);
        AllocStats { allocs: g(&ALLOCS), deallocs: g(&DEALLOCS), reallocs: g(&REALLOCS), bytes: g(&BYTES) }
    }
    /// Counters accumulated since `earlier`.
    pub fn since(earlier: AllocStats) -> Self {
        let n = Self::now();
        AllocStats {
            allocs: n.allocs - earlier.allocs,
            deallocs: n.deallocs - earlier.deallocs,
            reallocs: n.reallocs - earlier.reallocs,
            bytes: n.bytes - earlier.bytes,
        }
    }
    /// Allocations that were not freed within the region (growth).
    pub fn net(&self) -> i64 {
        self.allocs as i64 - self.deallocs as i64
    }
}

/// Run `f` and return its result with what this thread allocated meanwhile.
pub fn count<R>(f: impl FnOnce() -> R) -> (R, AllocStats) {
    let before = AllocStats::now();
    let r = f();
    (r, AllocStats::since(before))
}

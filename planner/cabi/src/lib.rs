//! dkrrt-plan-cabi: the checks `dkrrt plan` plans with, behind a C ABI, so that a reference
//! planner (OMPL, `bench/ompl_compare.cpp`) plans the same problem files with exactly the same
//! checks and its paths are timed and judged exactly as dkrrt's own.
//!
//! * [`dk_problem_open`]: a problem file made ready ([`dkrrt_rrt::problem::Prepared`]: the
//!   same world, δ and limits as `dkrrt plan`).
//! * [`dk_state_clear`], [`dk_segment_clear`]: RRT-Connect's checks
//!   ([`dkrrt_rrt::connect::Connect::segment_clear`]: a straight joint-space segment, sampled
//!   so that no point of the arm moves more than δ between samples).
//! * [`dk_path_duration`]: a path of rest configurations timed by the planner's rest-to-rest
//!   motions and given the final check of `dkrrt plan` (the message's sampled check, then the
//!   clearance every 1 ms).
//!
//! Every call counts itself and the time spent in it, so a harness can tell its own time from
//! the checker's. Null handles and pointers are refused (`-1`), never dereferenced.

use std::ffi::{c_char, c_int, CStr};
use std::path::Path;
use std::time::Instant;

use dkrrt_msg::{Trajectory, Zeroed, NJ};
use dkrrt_rrt::connect::Connect;
use dkrrt_rrt::problem::{load, Prepared, Problem};

/// A problem made ready, with its counters. Opaque to C.
pub struct DkProblem {
    problem: Problem,
    prep: Prepared,
    connect: Connect,
    out: Box<Trajectory>,
    q_min: [f64; NJ],
    q_max: [f64; NJ],
    counts: DkCounts,
}

/// What the checks of a problem have done so far.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DkCounts {
    /// Calls of [`dk_state_clear`] and [`dk_segment_clear`].
    pub states: u64,
    pub segments: u64,
    /// Configurations the checker measured in them (every sample of a segment).
    pub configs: u64,
    /// Time spent inside the two, s.
    pub check_s: f64,
}

/// Joint count of the arm (the length of every configuration array).
pub const DK_NJ: usize = NJ;

fn write_err(buf: *mut c_char, len: usize, msg: &str) {
    if buf.is_null() || len == 0 {
        return;
    }
    let bytes = msg.as_bytes();
    let n = bytes.len().min(len - 1);
    // SAFETY: the caller gives `buf` with room for `len` bytes; we write n < len, then a NUL.
    unsafe {
        std::ptr::copy_nonoverlapping(bytes.as_ptr(), buf as *mut u8, n);
        *buf.add(n) = 0;
    }
}

/// Opens a problem file (format: docs/planning-problem.md) for the shipped scenario's motion
/// limits, as `dkrrt plan` does; `time_limit_s > 0` overrides the file's time limit. On error,
/// returns null and writes the message (naming the file and the field) into `err`
/// (`err_len` bytes, NUL-terminated; `err` may be null).
///
/// # Safety
/// `path` is a NUL-terminated string; `err` is null or holds `err_len` bytes.
#[no_mangle]
pub unsafe extern "C" fn dk_problem_open(
    path: *const c_char,
    time_limit_s: f64,
    err: *mut c_char,
    err_len: usize,
) -> *mut DkProblem {
    if path.is_null() {
        write_err(err, err_len, "dk_problem_open: path is null");
        return std::ptr::null_mut();
    }
    // SAFETY: non-null, NUL-terminated by the contract above.
    let path = match unsafe { CStr::from_ptr(path) }.to_str() {
        Ok(s) => Path::new(s).to_path_buf(),
        Err(_) => {
            write_err(err, err_len, "dk_problem_open: path is not UTF-8");
            return std::ptr::null_mut();
        }
    };
    match open(&path, (time_limit_s > 0.0).then_some(time_limit_s)) {
        Ok(p) => Box::into_raw(Box::new(p)),
        Err(e) => {
            write_err(err, err_len, &e);
            std::ptr::null_mut()
        }
    }
}

/// [`dk_problem_open`] for Rust callers.
pub fn open(path: &Path, time_limit: Option<f64>) -> Result<DkProblem, String> {
    let (problem, model) = load(path, time_limit)?;
    let l = *model.limits();
    let m = dkrrt_config::Scenario::default_scenario().motion;
    let prep = Prepared::new(&problem, model, m.v_max, m.a_max, m.j_max)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    let connect = prep.connect(1, problem.seed);
    Ok(DkProblem {
        problem,
        prep,
        connect,
        out: Box::new(<Trajectory as Zeroed>::zeroed()),
        q_min: l.q_min.into(),
        q_max: l.q_max.into(),
        counts: DkCounts::default(),
    })
}

/// Frees a problem (null: nothing).
///
/// # Safety
/// `h` is null or a handle from [`dk_problem_open`], not used afterwards.
#[no_mangle]
pub unsafe extern "C" fn dk_problem_close(h: *mut DkProblem) {
    if !h.is_null() {
        // SAFETY: from Box::into_raw in dk_problem_open, freed once.
        drop(unsafe { Box::from_raw(h) });
    }
}

/// What a problem is: its start, goal, joint limits (arrays of [`DK_NJ`]), time limit and seed.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DkInfo {
    pub start: [f64; NJ],
    pub goal: [f64; NJ],
    pub q_min: [f64; NJ],
    pub q_max: [f64; NJ],
    pub time_limit_s: f64,
    pub seed: u64,
    /// 1: no obstacle moves and the start and goal leave δ/2 (joint-space planning applies,
    /// as `dkrrt plan`'s RRT-Connect); 0: not.
    pub still: c_int,
    /// Clearances of the start (t = 0) and of the goal (after the last pose), m; < 0: in collision.
    pub start_clear_m: f64,
    pub goal_clear_m: f64,
    /// The δ the checks use, m.
    pub delta_m: f64,
}

impl DkProblem {
    /// See [`DkInfo`].
    pub fn info(&self) -> DkInfo {
        DkInfo {
            start: self.problem.start,
            goal: self.problem.goal,
            q_min: self.q_min,
            q_max: self.q_max,
            time_limit_s: self.problem.time_limit_s,
            seed: self.problem.seed,
            still: self.prep.still as c_int,
            start_clear_m: self.prep.start_clear,
            goal_clear_m: self.prep.goal_clear,
            delta_m: self.prep.planner.cfg.delta_m,
        }
    }

    /// Whether the straight segment `a → b` is clear (a = b: the configuration); counted.
    pub fn segment_clear(&mut self, a: &[f64; NJ], b: &[f64; NJ]) -> bool {
        let t = Instant::now();
        let before = self.prep.planner.checker.configs_checked;
        let Prepared { planner, world, .. } = &mut self.prep;
        let ok = self.connect.segment_clear(&mut planner.checker, world, a, b);
        let c = &mut self.counts;
        if a == b {
            c.states += 1;
        } else {
            c.segments += 1;
        }
        c.configs += self.prep.planner.checker.configs_checked - before;
        c.check_s += t.elapsed().as_secs_f64();
        ok
    }

    /// The path (rest configurations, start to goal) timed as `dkrrt plan` times its own, and
    /// given its final check: (duration [s], smallest clearance [m], passed; the clearance is
    /// infinite when nothing came within 100 m); `None`: the path could not be timed (a
    /// motion, or more motions than a message carries).
    pub fn path_duration(&mut self, path: &[[f64; NJ]]) -> Option<(f64, f64, bool)> {
        self.prep.time_path(path, &mut self.out)?;
        let (ok, m) = self.prep.verify(&self.out);
        // Nothing within the measured range: no figure, as `dkrrt plan` says (null there).
        let m = if m < dkrrt_rrt::problem::MEASURED_UP_TO_M { m } else { f64::INFINITY };
        Some((self.out.duration_s, m, ok))
    }

    /// The counters so far.
    pub fn counts(&self) -> DkCounts {
        self.counts
    }
}

/// Writes the problem's [`DkInfo`] into `out`. 0, or -1 for a null argument.
///
/// # Safety
/// `h` is null or a live handle; `out` is null or points to a `DkInfo`.
#[no_mangle]
pub unsafe extern "C" fn dk_problem_info(h: *const DkProblem, out: *mut DkInfo) -> c_int {
    // SAFETY: null or valid by the contract.
    match unsafe { (h.as_ref(), out.as_mut()) } {
        (Some(h), Some(o)) => {
            *o = h.info();
            0
        }
        _ => -1,
    }
}

/// 1: the configuration `q` ([`DK_NJ`] values) is clear (within the joint limits, δ/2 from
/// every obstacle inflated by the margin); 0: not; -1: a null argument.
///
/// # Safety
/// `h` is null or a live handle; `q` is null or points to [`DK_NJ`] values.
#[no_mangle]
pub unsafe extern "C" fn dk_state_clear(h: *mut DkProblem, q: *const f64) -> c_int {
    // SAFETY: null or valid by the contract.
    let (Some(h), Some(q)) = (unsafe { h.as_mut() }, unsafe { q.cast::<[f64; NJ]>().as_ref() }) else {
        return -1;
    };
    h.segment_clear(q, q) as c_int
}

/// 1: the straight joint-space segment `a → b` is clear at every sample (samples no more than
/// δ of arm motion apart); 0: not; -1: a null argument.
///
/// # Safety
/// `h` is null or a live handle; `a`, `b` are null or point to [`DK_NJ`] values each.
#[no_mangle]
pub unsafe extern "C" fn dk_segment_clear(h: *mut DkProblem, a: *const f64, b: *const f64) -> c_int {
    // SAFETY: null or valid by the contract.
    let (Some(h), Some(a), Some(b)) =
        (unsafe { h.as_mut() }, unsafe { a.cast::<[f64; NJ]>().as_ref() }, unsafe {
            b.cast::<[f64; NJ]>().as_ref()
        })
    else {
        return -1;
    };
    h.segment_clear(a, b) as c_int
}

/// Times `n` waypoints (`n × DK_NJ` values, start first, goal last) by the planner's
/// rest-to-rest motions and checks the timed trajectory as `dkrrt plan` checks its own.
/// Returns the duration [s] and writes the smallest clearance [m] into `min_clearance_m`
/// (may be null); 1 into `passed` if the check passed, else 0 (may be null). Returns -1 for
/// a null argument or `n < 2`, -2 when the path cannot be timed.
///
/// # Safety
/// `h` is null or a live handle; `path` is null or holds `n × DK_NJ` values; the outputs are
/// null or valid.
#[no_mangle]
pub unsafe extern "C" fn dk_path_duration(
    h: *mut DkProblem,
    path: *const f64,
    n: usize,
    min_clearance_m: *mut f64,
    passed: *mut c_int,
) -> f64 {
    // SAFETY: null or valid by the contract.
    let Some(h) = (unsafe { h.as_mut() }) else { return -1.0 };
    if path.is_null() || n < 2 {
        return -1.0;
    }
    // SAFETY: `path` holds n × NJ values by the contract.
    let pts = unsafe { std::slice::from_raw_parts(path.cast::<[f64; NJ]>(), n) };
    match h.path_duration(pts) {
        Some((d, m, ok)) => {
            // SAFETY: null or valid by the contract.
            if let Some(x) = unsafe { min_clearance_m.as_mut() } {
                *x = m;
            }
            if let Some(x) = unsafe { passed.as_mut() } {
                *x = ok as c_int;
            }
            d
        }
        None => -2.0,
    }
}

/// Writes the counters into `out`. 0, or -1 for a null argument.
///
/// # Safety
/// `h` is null or a live handle; `out` is null or points to a `DkCounts`.
#[no_mangle]
pub unsafe extern "C" fn dk_problem_counts(h: *const DkProblem, out: *mut DkCounts) -> c_int {
    // SAFETY: null or valid by the contract.
    match unsafe { (h.as_ref(), out.as_mut()) } {
        (Some(h), Some(o)) => {
            *o = h.counts();
            0
        }
        _ => -1,
    }
}

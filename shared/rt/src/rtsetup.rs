//! Optional real-time setup: SCHED_FIFO priority, mlockall, CPU pinning.
//! Each step falls back with a warning where the system does not permit it.

/// What to ask for.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RtOptions {
    /// SCHED_FIFO priority 1..=99; 0 keeps the normal scheduler.
    pub fifo_priority: u32,
    /// Lock current and future memory (no page faults in the loop).
    pub mlockall: bool,
    /// Pin the calling thread to this CPU.
    pub cpu: Option<usize>,
}

impl RtOptions {
    /// From scenario values: `cpu < 0` means no pinning, priority 0 no SCHED_FIFO.
    pub fn new(cpu: i32, fifo_priority: u32, mlockall: bool) -> Self {
        RtOptions { fifo_priority, mlockall, cpu: (cpu >= 0).then_some(cpu as usize) }
    }
}

/// Applies `opt` only for clock-paced (real-time) loops: lockstep loops spin,
/// and spinning SCHED_FIFO processes would starve the rest of the machine.
pub fn apply_if(realtime: bool, opt: &RtOptions) -> RtReport {
    if realtime {
        apply(opt)
    } else {
        RtReport::default()
    }
}

/// Sets the calling thread's timer slack to 1 ns (the default 50 µs slack
/// would delay every absolute-deadline wake-up of a normal-priority thread).
pub fn tight_timer_slack() -> bool {
    // SAFETY: plain prctl on the calling thread.
    unsafe { libc::prctl(libc::PR_SET_TIMERSLACK, 1 as libc::c_ulong) == 0 }
}

/// What was granted; `warnings` says what fell back and why.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct RtReport {
    pub timer_slack_1ns: bool,
    pub fifo: bool,
    pub mlockall: bool,
    pub pinned_cpu: Option<usize>,
    pub warnings: Vec<String>,
}

fn os_err() -> String {
    std::io::Error::last_os_error().to_string()
}

/// Applies `opt` to the calling thread/process.
pub fn apply(opt: &RtOptions) -> RtReport {
    let mut r = RtReport::default();
    r.timer_slack_1ns = tight_timer_slack();
    if opt.mlockall {
        // SAFETY: plain syscall.
        if unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) } == 0 {
            r.mlockall = true;
        } else {
            r.warnings.push(format!("mlockall not permitted ({}); continuing unlocked", os_err()));
        }
    }
    if opt.fifo_priority > 0 {
        let p = libc::sched_param { sched_priority: opt.fifo_priority.min(99) as i32 };
        // SAFETY: valid sched_param; 0 = calling thread.
        if unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &p) } == 0 {
            r.fifo = true;
        } else {
            r.warnings.push(format!(
                "SCHED_FIFO priority {} not permitted ({}); using the normal scheduler",
                opt.fifo_priority,
                os_err()
            ));
        }
    }
    if let Some(cpu) = opt.cpu {
        // SAFETY: cpu_set_t is plain data; CPU_SET bounds-checks against its size.
        unsafe {
            let mut set: libc::cpu_set_t = core::mem::zeroed();
            let ncpu = libc::sysconf(libc::_SC_NPROCESSORS_ONLN).max(1) as usize;
            if cpu < ncpu {
                libc::CPU_SET(cpu, &mut set);
                if libc::sched_setaffinity(0, core::mem::size_of::<libc::cpu_set_t>(), &set) == 0 {
                    r.pinned_cpu = Some(cpu);
                } else {
                    r.warnings.push(format!("pinning to CPU {cpu} failed ({}); not pinned", os_err()));
                }
            } else {
                r.warnings.push(format!("CPU {cpu} does not exist (machine has {ncpu}); not pinned"));
            }
        }
    }
    r
}

/// Puts the calling thread back on the normal scheduler, free to run on any online CPU: for
/// a helper thread spawned by a real-time thread (it inherits SCHED_FIFO and the pinning),
/// whose work must never hold the real-time loop's CPU at its priority. Returns whether both
/// took effect (they cannot fail for a thread's own, lower settings).
pub fn demote_current_thread() -> bool {
    let p = libc::sched_param { sched_priority: 0 };
    // SAFETY: valid sched_param; 0 = calling thread.
    let sched = unsafe { libc::sched_setscheduler(0, libc::SCHED_OTHER, &p) } == 0;
    // SAFETY: cpu_set_t is plain data; CPU_SET bounds-checks against its size.
    let pinned = unsafe {
        let mut set: libc::cpu_set_t = core::mem::zeroed();
        let ncpu = libc::sysconf(libc::_SC_NPROCESSORS_ONLN).max(1) as usize;
        for c in 0..ncpu.min(libc::CPU_SETSIZE as usize) {
            libc::CPU_SET(c, &mut set);
        }
        libc::sched_setaffinity(0, core::mem::size_of::<libc::cpu_set_t>(), &set) == 0
    };
    sched && pinned
}

#[cfg(test)]
mod demote_tests {
    /// A helper thread of a real-time thread returns to the normal scheduler on any CPU.
    #[test]
    fn a_demoted_thread_runs_on_the_normal_scheduler_on_every_cpu() {
        let h = std::thread::spawn(|| {
            // SAFETY: plain syscalls on the calling thread with plain-data sets.
            unsafe {
                // Pinned to CPU 0 first (always permitted), as a real-time parent leaves it.
                let mut one: libc::cpu_set_t = core::mem::zeroed();
                libc::CPU_SET(0, &mut one);
                assert_eq!(libc::sched_setaffinity(0, core::mem::size_of::<libc::cpu_set_t>(), &one), 0);
                assert!(super::demote_current_thread());
                let mut set: libc::cpu_set_t = core::mem::zeroed();
                assert_eq!(libc::sched_getaffinity(0, core::mem::size_of::<libc::cpu_set_t>(), &mut set), 0);
                let ncpu = libc::sysconf(libc::_SC_NPROCESSORS_ONLN) as usize;
                assert_eq!(libc::CPU_COUNT(&set) as usize, ncpu);
                assert_eq!(libc::sched_getscheduler(0), libc::SCHED_OTHER);
            }
        });
        h.join().unwrap();
    }
}

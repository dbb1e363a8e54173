//! `dkrrt launch`: starts sim, the debris predictor (when the scenario has debris), tracker
//! and the trajectory source as separate
//! OS processes on a private iceoryx2 run, supervises them, and writes the
//! run report.
//!
//! * Before starting, stale iceoryx2 resources of dead dkrrt nodes of earlier
//!   runs are removed.
//! * It waits until every process's node is alive on the bus.
//! * The run id is refused if a node of that run is alive, or if it is malformed; the run's
//!   files live in a fresh owner-only directory (0700, unpredictable name, never followed
//!   through a symlink).
//! * SIGINT/SIGTERM (or the time limit) is a controlled stop: every process gets SIGTERM at
//!   once; the sim keeps stepping with `FLAG_STOPPING` until the tracker has braked the arm to
//!   rest, then ends the run; sources and predictor just exit.
//! * If the sim or the tracker dies, the others are stopped after a short grace period (the
//!   tracker's safe hold or the plant's brakes act first and are reported). A dead or hung
//!   goto, planner or predictor fails the run but does not end it: the tracker finishes or
//!   brakes on what it has (a hung one is killed).
//! * A process whose heartbeat stops for [`HEARTBEAT_TIMEOUT_NS`] is treated as hung.
//! * The verdict ([`crate::verdict`]): `ok` only when every check passed.

use std::collections::BTreeSet;
use std::os::unix::process::{CommandExt, ExitStatusExt};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

use dkrrt_config::{Mode, Scenario};
use dkrrt_msg::bus::{run_config, Bus};
use dkrrt_msg::{Heartbeat, Source};
use dkrrt_rt::clock::mono_ns;
use dkrrt_rt::signals;
use serde_json::{json, Value};

/// A process whose heartbeat is older than this (after its first one) is hung.
pub const HEARTBEAT_TIMEOUT_NS: u64 = 2_000_000_000;
/// How long the launcher lets the others react after the sim or the tracker died.
pub const GRACE_NS: u64 = 300_000_000;
/// How long a controlled stop may take before the launcher kills what is left (the sim's own
/// stop limit is 15 s of plant time).
pub const STOP_KILL_NS: u64 = 25_000_000_000;

/// The node name of `dkrrt goal` (a user's goal sent to a live run; not a rogue).
pub const GOAL_CLI_NODE: &str = "goal-cli";

/// Processes whose death ends the run (the arm cannot be controlled without them).
fn critical(name: &str) -> bool {
    matches!(name, "sim" | "driver" | "tracker")
}

/// The process name of the arm emulator (`--driver udp`): the "hardware", not on the bus.
pub const EMULATOR: &str = "arm-emulator";

/// Which process drives the arm.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Driver {
    /// `dkrrt sim`: the plant simulator on the bus.
    #[default]
    Sim,
    /// `dkrrt udp-driver` talking over UDP (loopback) to `dkrrt arm-emulator`.
    Udp,
}

impl Driver {
    /// The driver's process (and bus node) name.
    pub fn process(self) -> &'static str {
        match self {
            Driver::Sim => "sim",
            Driver::Udp => "driver",
        }
    }
}

/// Two free UDP ports on loopback, for the driver and the arm emulator (the kernel picks them;
/// they are released just before the processes bind them).
fn free_udp_pair() -> Result<(std::net::SocketAddr, std::net::SocketAddr), String> {
    let a = std::net::UdpSocket::bind("127.0.0.1:0").map_err(|e| format!("udp port: {e}"))?;
    let b = std::net::UdpSocket::bind("127.0.0.1:0").map_err(|e| format!("udp port: {e}"))?;
    let addr = |s: &std::net::UdpSocket| s.local_addr().map_err(|e| format!("udp port: {e}"));
    Ok((addr(&a)?, addr(&b)?))
}

/// Random hex digits from the kernel (run ids, directory names nobody can guess).
pub fn random_hex(bytes: usize) -> String {
    let mut b = vec![0u8; bytes];
    // SAFETY: getrandom(2) writes at most b.len() bytes into b.
    let n = unsafe { libc::getrandom(b.as_mut_ptr().cast(), b.len(), 0) };
    if n != b.len() as isize {
        // Never expected on Linux; fall back on the clock and pid (still unique per launch).
        let x = mono_ns() ^ ((std::process::id() as u64) << 32);
        b.iter_mut().enumerate().for_each(|(i, v)| *v = (x >> ((i % 8) * 8)) as u8);
    }
    b.iter().map(|v| format!("{v:02x}")).collect()
}

/// A fresh owner-only (0700) directory in the temp dir with an unpredictable name; fails
/// rather than reuse anything already there (no symlink is followed).
pub fn private_dir(tag: &str) -> Result<PathBuf, String> {
    use std::os::unix::fs::DirBuilderExt;
    for _ in 0..8 {
        let d = std::env::temp_dir().join(format!("dkrrt-{tag}-{}", random_hex(8)));
        match std::fs::DirBuilder::new().mode(0o700).create(&d) {
            Ok(()) => return Ok(d),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(format!("create {}: {e}", d.display())),
        }
    }
    Err("could not create a private run directory".into())
}

/// Checks that `p` can be written (its directory exists and takes files) without leaving
/// anything behind.
pub fn check_writable(p: &Path) -> Result<(), String> {
    let existed = p.exists();
    std::fs::OpenOptions::new().append(true).create(true).open(p).map_err(|e| e.to_string())?;
    if !existed {
        let _ = std::fs::remove_file(p);
    }
    Ok(())
}

/// Writes a new owner-only (0600) file; refuses an existing path (or symlink).
pub fn write_private(p: &Path, text: &str) -> Result<(), String> {
    use std::io::Write;
    use std::os::unix::fs::OpenOptionsExt;
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(0o600)
        .open(p)
        .and_then(|mut f| f.write_all(text.as_bytes()))
        .map_err(|e| format!("write {}: {e}", p.display()))
}

pub struct LaunchOptions {
    pub scenario: Scenario,
    pub report: PathBuf,
    pub run: Option<String>,
    pub quiet: bool,
    /// Draw Fig. 2, Fig. 4 and the clearance plot of the run into this directory (the sim and
    /// the tracker keep traces for it).
    pub figures: Option<PathBuf>,
    /// Record every service of the run into this MCAP file (`dkrrt recorder`).
    pub record: Option<PathBuf>,
    /// Which process drives the arm.
    pub driver: Driver,
}

struct Proc {
    name: &'static str,
    child: Child,
    stats: PathBuf,
    exit: Option<std::process::ExitStatus>,
    last_heartbeat_ns: Option<u64>,
    heartbeats: u64,
    /// Restarts so far, and when the next one is due (`supervision`).
    restarts: u32,
    respawn_at: Option<u64>,
}

fn spawn(
    exe: &Path,
    name: &'static str,
    run: &str,
    scenario: &Path,
    stats: &Path,
    planner: bool,
    trace: Option<&Path>,
    restart: u32,
    udp: Option<(std::net::SocketAddr, std::net::SocketAddr)>,
) -> std::io::Result<Child> {
    let mut cmd = Command::new(exe);
    if let (EMULATOR, Some((driver, arm))) = (name, udp) {
        cmd.arg(EMULATOR).arg("--scenario").arg(scenario).arg("--stats").arg(stats);
        cmd.arg("--listen").arg(arm.to_string()).arg("--driver").arg(driver.to_string()).stdin(Stdio::null());
        die_with_parent(&mut cmd);
        return cmd.spawn();
    }
    if let ("driver", Some((driver, arm))) = (name, udp) {
        cmd.arg("udp-driver").arg("--listen").arg(driver.to_string()).arg("--arm").arg(arm.to_string());
    } else if name == "sim" {
        // Lockstep: plant time starts once the observations have their reader (with debris,
        // where the launcher starts a predictor) and, with goto, once the trajectory is out;
        // with the planner, it waits for each planning cycle instead.
        cmd.arg(name).arg("--gate-predictor");
        cmd.arg(if planner { "--gate-planner" } else { "--gate-trajectory" });
    } else {
        cmd.arg(name);
    }
    cmd.arg("--run").arg(run).arg("--scenario").arg(scenario).arg("--stats").arg(stats).stdin(Stdio::null());
    if let Some(t) = trace {
        cmd.arg("--trace").arg(t);
    }
    if name == "planner" && restart > 0 {
        cmd.arg("--restart").arg(restart.to_string());
    }
    die_with_parent(&mut cmd);
    cmd.spawn()
}

/// The child gets SIGTERM (a controlled stop) when the launcher dies.
fn die_with_parent(cmd: &mut Command) {
    // SAFETY: prctl is async-signal-safe; the child dies with the launcher.
    unsafe {
        cmd.pre_exec(|| {
            libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM);
            Ok(())
        });
    }
}

impl Proc {
    fn new(name: &'static str, child: Child, stats: PathBuf) -> Proc {
        Proc {
            name,
            child,
            stats,
            exit: None,
            last_heartbeat_ns: None,
            heartbeats: 0,
            restarts: 0,
            respawn_at: None,
        }
    }
}

fn signal(child: &Child, sig: i32) {
    // SAFETY: plain kill(2) on our own child's pid.
    unsafe { libc::kill(child.id() as i32, sig) };
}

/// Run ids of dkrrt iceoryx2 resources present on the machine.
fn dkrrt_runs_on_machine() -> BTreeSet<String> {
    let mut runs = BTreeSet::new();
    let root = PathBuf::from(run_config("x").map(|c| c.global.root_path().to_string()).unwrap_or_default());
    let mut dirs = vec![PathBuf::from("/dev/shm"), root.clone()];
    if let Ok(rd) = std::fs::read_dir(&root) {
        dirs.extend(rd.flatten().map(|e| e.path()).filter(|p| p.is_dir()));
    }
    for d in dirs {
        for e in std::fs::read_dir(&d).into_iter().flatten().flatten() {
            let n = e.file_name().to_string_lossy().to_string();
            if let Some(rest) = n.strip_prefix("dkrrt_") {
                if let Some(run) = rest.split('_').next() {
                    if !run.is_empty() {
                        runs.insert(run.to_string());
                    }
                }
            }
        }
    }
    runs
}

/// Removes the stale resources of dead dkrrt nodes of every run on the machine.
pub fn remove_stale_everywhere() -> usize {
    dkrrt_runs_on_machine()
        .iter()
        .filter_map(|r| run_config(r).ok())
        .map(|c| Bus::remove_stale(&c).unwrap_or(0))
        .sum()
}

fn status_json(p: &Proc) -> Value {
    let (code, sig) = match p.exit {
        Some(s) => (s.code(), s.signal()),
        None => (None, None),
    };
    json!({
        "name": p.name,
        "pid": p.child.id(),
        "exit_code": code,
        "signal": sig,
        "heartbeats": p.heartbeats,
        "restarts": p.restarts,
    })
}

fn read_stats(p: &Path) -> Value {
    std::fs::read_to_string(p).ok().and_then(|t| serde_json::from_str(&t).ok()).unwrap_or(Value::Null)
}

fn pick(v: &Value, keys: &[&str]) -> Value {
    let mut o = serde_json::Map::new();
    for k in keys {
        o.insert(k.to_string(), v.get(*k).cloned().unwrap_or(Value::Null));
    }
    Value::Object(o)
}

/// Runs the process set; returns the report and whether the run was clean.
/// Why the process set refuses `oracle-rrt`.
pub const ORACLE_IN_PROCESS: &str = "planner.method = \"oracle-rrt\" plans on the true future of the debris, which only the in-process lockstep has: run it with `dkrrt eval` or `dkrrt study`, not as processes";

pub fn launch(opts: LaunchOptions) -> Result<(Value, bool), String> {
    signals::install();
    let sc = opts.scenario;
    if sc.forecasts() == dkrrt_config::Forecasts::Oracle {
        return Err(ORACLE_IN_PROCESS.into());
    }
    if opts.driver == Driver::Udp && sc.run.mode != Mode::Realtime {
        return Err("--driver udp: run.mode must be \"realtime\" (the arm emulator keeps its own clock; lockstep is the simulator's)".into());
    }
    if let Some(f) = &opts.figures {
        std::fs::create_dir_all(f).map_err(|e| format!("--figures {}: {e}", f.display()))?;
    }
    let t_start = mono_ns();
    let run = opts.run.unwrap_or_else(|| random_hex(8));
    let cfg = run_config(&run).map_err(|e| e.to_string())?;
    let cleaned = remove_stale_everywhere();
    if cleaned > 0 && !opts.quiet {
        println!("dkrrt: removed stale resources of {cleaned} dead node(s) of earlier runs");
    }
    // A live run id is refused (two launches on one bus would corrupt each other).
    let (alive, _) = Bus::nodes(&cfg).map_err(|e| e.to_string())?;
    if !alive.is_empty() {
        let names: Vec<String> = alive.iter().map(|(n, pid)| format!("{n} (pid {pid})")).collect();
        return Err(format!("run id {run} is live: {} on its bus; choose another --run", names.join(", ")));
    }
    let dir = private_dir(&run)?;
    // Every process gets the exact same, fully resolved scenario.
    let mut resolved = sc.clone();
    if let Some(p) = sc.urdf_path() {
        resolved.robot.urdf = std::fs::canonicalize(&p).unwrap_or(p).display().to_string();
    }
    resolved.robot.package_path = sc
        .urdf_options()
        .package_path
        .into_iter()
        .map(|p| std::fs::canonicalize(&p).unwrap_or(p).display().to_string())
        .collect();
    if opts.driver == Driver::Udp && !resolved.tracker.follow_states {
        // The arm's clock and the network set when states arrive: the tracker follows them.
        resolved.tracker.follow_states = true;
    }
    if let Some(p) = sc.debris_scene_path() {
        resolved.debris.scene = std::fs::canonicalize(&p).unwrap_or(p).display().to_string();
    }
    if let Some(p) = sc.predictor_model_path() {
        resolved.predictor.model = std::fs::canonicalize(&p).unwrap_or(p).display().to_string();
    }
    // A resolved threat episode: its generated scene as a file, the scenario as plain data.
    if let Some(scene) = &sc.scene_override {
        let p = dir.join("scene.toml");
        write_private(&p, &scene.to_toml())?;
        resolved.debris.scene = p.display().to_string();
        resolved.episode = None;
    }
    let sc_path = dir.join("scenario.toml");
    write_private(&sc_path, &resolved.to_toml())?;
    let exe = std::env::current_exe().map_err(|e| e.to_string())?;

    let bus = Bus::new(&run, "launcher").map_err(|e| e.to_string())?;
    let mut hb_sub = bus.subscriber::<Heartbeat>().map_err(|e| e.to_string())?;
    let lim = dkrrt_msg::ContractLimits::symmetric(0.0, 0.0, 0.0);

    let mut procs: Vec<Proc> = Vec::new();
    // The recorder first, so it is on the bus when the others start publishing.
    if let Some(out) = &opts.record {
        let stats = dir.join("recorder.json");
        let mut cmd = Command::new(&exe);
        cmd.arg("recorder").arg("--run").arg(&run).arg("--out").arg(out).arg("--stats").arg(&stats);
        cmd.stdin(Stdio::null());
        die_with_parent(&mut cmd);
        let child = cmd.spawn().map_err(|e| format!("start recorder: {e}"))?;
        println!("dkrrt: started recorder pid {}", child.id());
        procs.push(Proc::new("recorder", child, stats));
    }
    let planner = sc.replans();
    let source: &'static str = if planner { "planner" } else { "goto" };
    let driver = opts.driver.process();
    let udp = match opts.driver {
        Driver::Sim => None,
        Driver::Udp => Some(free_udp_pair()?),
    };
    // The arm first (it is powered on before its driver connects).
    let mut names: Vec<&'static str> = if udp.is_some() { vec![EMULATOR, driver] } else { vec![driver] };
    if sc.has_debris() {
        names.push("predictor");
    }
    names.extend(["tracker", source]);
    for name in names {
        let stats = dir.join(format!("{name}.json"));
        let _ = std::fs::remove_file(&stats);
        let trace = (opts.figures.is_some() && matches!(name, "sim" | "tracker" | "planner"))
            .then(|| dir.join(format!("{name}-trace.json")));
        let child = spawn(&exe, name, &run, &sc_path, &stats, planner, trace.as_deref(), 0, udp)
            .map_err(|e| format!("start {name}: {e}"))?;
        println!("dkrrt: started {name} pid {}", child.id());
        procs.push(Proc::new(name, child, stats));
    }

    let mut failure: Option<String> = None;
    let mut ready = false;
    let ready_deadline = mono_ns() + 15_000_000_000;
    let hard_deadline = mono_ns()
        + match sc.run.mode {
            Mode::Realtime => ((sc.run.duration_s + 20.0) * 1e9) as u64,
            Mode::Lockstep => ((sc.run.duration_s * 20.0 + 60.0) * 1e9) as u64,
        };
    // `stop_at`: when the whole set was told to stop (SIGTERM: a controlled stop);
    // `end_at`: when the run is over for the launcher (the sim ended, or the sim or the
    // tracker died): the rest get SIGTERM after a grace period.
    let mut stop_at: Option<u64> = None;
    let mut kill_sent = false;
    // The arm emulator's power-off (SIGTERM) was sent: once, not every loop turn.
    let mut arm_off_sent = false;
    let mut end_at: Option<u64> = None;
    let mut rogue: Vec<(String, u32)> = Vec::new();
    let mut restarts: Vec<Value> = Vec::new();
    let mut visitors: Vec<u32> = Vec::new();
    let mut next_node_scan = 0u64;

    loop {
        let now = mono_ns();
        // Heartbeats.
        let _ = hb_sub.for_each(&lim, |h| {
            if let Some(src) = Source::from_u32(h.header.source) {
                if let Some(p) = procs.iter_mut().find(|p| p.name == src.name()) {
                    p.last_heartbeat_ns = Some(now);
                    p.heartbeats += 1;
                }
            }
        });
        // Exits.
        let mut died = false;
        for p in procs.iter_mut().filter(|p| p.exit.is_none()) {
            if let Ok(Some(st)) = p.child.try_wait() {
                p.exit = Some(st);
                if !st.success() && stop_at.is_none() {
                    died = true;
                    let what = match st.signal() {
                        Some(s) => format!("process {} died (signal {s})", p.name),
                        None => format!("process {} failed (exit code {})", p.name, st.code().unwrap_or(-1)),
                    };
                    eprintln!("dkrrt: {what}{}", if critical(p.name) { "" } else { "; the run goes on" });
                    failure.get_or_insert(what);
                    if critical(p.name) {
                        end_at.get_or_insert(now);
                    } else if sc.supervision.restarts(p.name)
                        && p.restarts < sc.supervision.max_restarts
                        && end_at.is_none()
                    {
                        let backoff = sc.supervision.backoff_ms * 1e6 * f64::from(1u32 << p.restarts.min(16));
                        p.respawn_at = Some(now + backoff as u64);
                    }
                }
                if st.success() && p.name == driver {
                    // The end of the run: the others follow the end-of-run flag.
                    end_at.get_or_insert(now);
                }
            }
        }
        if died {
            // The dead node's ports leave the bus, so nobody waits on them (the lockstep sim's
            // gates see the publisher gone).
            let _ = Bus::remove_stale(&cfg);
        }
        // Restarts due (supervision): the process resumes from the live bus.
        for p in procs.iter_mut() {
            if p.respawn_at.is_some_and(|t| now >= t) {
                p.respawn_at = None;
                if stop_at.is_some() || end_at.is_some() {
                    continue;
                }
                p.restarts += 1;
                let stats = dir.join(format!("{}-r{}.json", p.name, p.restarts));
                let trace = (opts.figures.is_some() && p.name == "planner")
                    .then(|| dir.join(format!("{}-r{}-trace.json", p.name, p.restarts)));
                match spawn(&exe, p.name, &run, &sc_path, &stats, planner, trace.as_deref(), p.restarts, udp)
                {
                    Ok(child) => {
                        println!("dkrrt: restarted {} pid {} (restart {})", p.name, child.id(), p.restarts);
                        restarts.push(json!({
                            "name": p.name,
                            "restart": p.restarts,
                            "t_s": (now - t_start) as f64 * 1e-9,
                            "old_pid": p.child.id(),
                            "new_pid": child.id(),
                        }));
                        p.child = child;
                        p.stats = stats;
                        p.exit = None;
                        p.last_heartbeat_ns = None;
                    }
                    Err(e) => eprintln!("dkrrt: restart {}: {e}", p.name),
                }
            }
        }
        if procs.iter().all(|p| p.exit.is_some() && p.respawn_at.is_none()) {
            break;
        }
        // Nodes on the run's bus that the launcher did not start (a rogue `goto` or `sim` on a
        // live run id): reported, and the run fails.
        if ready && now >= next_node_scan {
            next_node_scan = now + 100_000_000;
            if let Ok((alive, _)) = Bus::nodes(&cfg) {
                for (name, pid) in alive {
                    let ours = pid == std::process::id() || procs.iter().any(|p| p.child.id() == pid);
                    // `dkrrt goal` (node `goal-cli`) is how a user talks to a live run: a visitor,
                    // listed, not a rogue.
                    if !ours && name == GOAL_CLI_NODE {
                        if !visitors.contains(&pid) {
                            visitors.push(pid);
                        }
                        continue;
                    }
                    if !ours && !rogue.iter().any(|r: &(String, u32)| r.1 == pid) {
                        eprintln!(
                            "dkrrt: a process this run did not start joined its bus: {name} (pid {pid})"
                        );
                        rogue.push((name, pid));
                    }
                }
            }
        }
        if !ready {
            if let Ok((alive, _)) = Bus::nodes(&cfg) {
                ready = procs.iter().all(|p| p.name == EMULATOR || alive.iter().any(|(n, _)| n == p.name));
                if ready && !opts.quiet {
                    println!("dkrrt: all processes alive on run {run}");
                }
            }
            if !ready && now > ready_deadline && failure.is_none() {
                failure = Some("processes did not come up within 15 s".into());
                stop_at.get_or_insert(now);
            }
        } else if stop_at.is_none() && end_at.is_none() {
            for p in procs.iter().filter(|p| p.exit.is_none()) {
                if p.last_heartbeat_ns.is_some_and(|t| now > t + HEARTBEAT_TIMEOUT_NS) {
                    // (The arm emulator sends no heartbeats: it is the hardware, off the bus.)
                    let what = format!("process {} stopped sending heartbeats (hung)", p.name);
                    eprintln!("dkrrt: {what}");
                    failure.get_or_insert(what);
                    // A hung process is killed (it would not act on SIGTERM). A hung sim or
                    // tracker ends the run (the other one brakes); a hung source or predictor
                    // does not: the tracker goes on with what it has.
                    signal(&p.child, libc::SIGKILL);
                    if critical(p.name) {
                        end_at.get_or_insert(now);
                    }
                }
            }
        }
        if signals::stop_requested() && stop_at.is_none() {
            failure.get_or_insert(format!("stopped by signal {} (controlled stop)", signals::stop_signal()));
            stop_at = Some(now);
        }
        if now > hard_deadline && stop_at.is_none() {
            failure.get_or_insert("run exceeded its time limit (controlled stop)".into());
            stop_at = Some(now);
        }
        if let Some(t) = end_at {
            let grace = if failure.is_some() { GRACE_NS } else { 3_000_000_000 };
            if stop_at.is_none() && now > t + grace {
                stop_at = Some(now);
            }
        }
        // The controlled stop: SIGTERM to everyone at once (the sim brings the arm to rest
        // before it ends), SIGKILL for whatever is left long after.
        if stop_at == Some(now) {
            for p in procs.iter().filter(|p| p.exit.is_none() && p.name != EMULATOR) {
                signal(&p.child, libc::SIGTERM);
            }
        }
        // The arm is powered off once nothing else runs (its driver brought it to rest and
        // braked it, or is gone: then the arm's own abort has braked it).
        if !arm_off_sent && procs.iter().all(|p| p.exit.is_some() || p.name == EMULATOR) {
            for p in procs.iter().filter(|p| p.exit.is_none() && p.name == EMULATOR) {
                signal(&p.child, libc::SIGTERM);
            }
            arm_off_sent = true;
        }
        if let Some(t) = stop_at {
            if !kill_sent && now > t + STOP_KILL_NS {
                for p in procs.iter().filter(|p| p.exit.is_none()) {
                    eprintln!(
                        "dkrrt: {} did not stop within {} s; killing it",
                        p.name,
                        STOP_KILL_NS / 1_000_000_000
                    );
                    signal(&p.child, libc::SIGKILL);
                }
                kill_sent = true;
            }
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    drop(hb_sub);
    drop(bus);
    let _ = Bus::remove_stale(&cfg);
    dkrrt_msg::bus::remove_run_leftovers(&run);

    let stats_of =
        |name: &str| procs.iter().find(|p| p.name == name).map_or(Value::Null, |p| read_stats(&p.stats));
    // With the arm emulator, its true plant (limits, brakes, final state) is what the checks
    // read; the driver's measured figures are kept beside them.
    let emulator = stats_of(EMULATOR);
    let mut sim_view = stats_of(driver);
    if udp.is_some() && !sim_view.is_null() && !emulator.is_null() {
        sim_view["plant_measured"] = sim_view["plant"].take();
        for k in ["plant", "final_q", "final_qd"] {
            sim_view[k] = emulator[k].clone();
        }
    }
    let (sim, tr, goto, pred, plan) =
        (&sim_view, &stats_of("tracker"), &stats_of("goto"), &stats_of("predictor"), &stats_of("planner"));
    // The verdict: every check of the scenario's `[checks]`.
    let unclean: Vec<String> = procs
        .iter()
        .filter(|p| !p.exit.is_some_and(|s| s.success()))
        .map(|p| match p.exit.map(|s| (s.code(), s.signal())) {
            Some((_, Some(sig))) => format!("{}: signal {sig}", p.name),
            Some((Some(c), _)) => format!("{}: exit code {c}", p.name),
            _ => format!("{}: did not exit", p.name),
        })
        .collect();
    let ending = crate::verdict::Ending {
        failure: failure.clone(),
        unclean,
        rogue: rogue.iter().map(|(n, pid)| format!("{n} (pid {pid})")).collect(),
    };
    let checks = crate::verdict::checks(&sc, &ending, sim, tr, goto, plan, pred);
    let failed = crate::verdict::failed(&checks);
    let ok = failed.is_empty();
    let collision = sim.pointer("/debris/first_contact").filter(|c| !c.is_null()).map(|c| {
        format!(
            "collision: link {} hit debris {} at t = {:.3} s",
            c["link"],
            c["debris_id"],
            c["t_s"].as_f64().unwrap_or(f64::NAN)
        )
    });
    // The stop reason: what the supervisor saw first, else the first failed check.
    let stop_reason = match (&failure, &collision) {
        (Some(f), _) => f.clone(),
        (None, Some(c)) => c.clone(),
        (None, None) => match checks.iter().find(|c| !c.ok) {
            Some(c) => format!("run completed; check {} failed: {}", c.name, c.detail),
            None => "run completed".into(),
        },
    };
    let lat = |k: &str, full: bool| {
        let keys: &[&str] = if full { &["p50", "p99", "p999", "max"] } else { &["p50", "p99", "max"] };
        pick(tr.get(k).unwrap_or(&Value::Null), keys)
    };
    let link = if udp.is_some() {
        json!({
            // On the arm's clock: its state sent → the command answering it received.
            "round_trip_us": pick(emulator.get("round_trip_us").unwrap_or(&Value::Null), &["p50", "p99", "max"]),
            "command_echo_us": pick(sim.pointer("/link/command_echo_us").unwrap_or(&Value::Null), &["p50", "p99", "max"]),
            "turnaround_us": pick(sim.pointer("/link/turnaround_us").unwrap_or(&Value::Null), &["p50", "p99", "max"]),
            "state_interval_us": pick(sim.pointer("/link/state_interval_us").unwrap_or(&Value::Null), &["p50", "p99", "max"]),
            "states_lost": sim.pointer("/link/states/lost"),
            "states_late": sim.pointer("/link/states/late"),
            "states_duplicated": sim.pointer("/link/states/duplicates"),
            "invalid_datagrams": sim.pointer("/link/invalid"),
            "commands_sent": sim.pointer("/link/commands_sent"),
            "commands_lost": emulator.pointer("/from_driver/lost"),
            "commands_invalid": emulator.pointer("/arm/commands_invalid"),
            "commands_late": emulator.pointer("/arm/commands_stale"),
            "aborts": emulator.pointer("/arm/aborts"),
            "arm_missed_max": sim.pointer("/link/arm_missed_max"),
            "impairment": pick(&emulator, &["delay_ms", "jitter_ms", "loss", "duplicate", "reorder"]),
            "emulator": emulator,
        })
    } else {
        Value::Null
    };
    let report = json!({
        "ok": ok,
        "stop_reason": stop_reason,
        "failed_checks": failed,
        "checks": checks,
        "final_velocity_rad_s": sim.get("final_qd"),
        "stop": sim.get("stop"),
        "run_id": run,
        "scenario": sc.name,
        "mode": sc.run.mode,
        "duration_s": sim.get("ticks").and_then(Value::as_f64).map(|t| t / sc.run.control_hz),
        "wall_time_s": (mono_ns() - t_start) as f64 * 1e-9,
        "ticks": tr.get("ticks"),
        "deadline_misses": tr.get("deadline_misses"),
        "wake_latency_us": lat("wake_latency_us", true),
        "tick_compute_us": lat("tick_compute_us", false),
        "state_to_command_us": lat("state_to_command_us", false),
        "tracking_error_rad": tr.get("tracking_error_rad"),
        "final_error_rad": tr.get("final_error_rad"),
        "safe_hold": {
            "entries": tr.get("safe_hold_entries"),
            "events": tr.get("events"),
            "plant_brake_engagements": sim.pointer("/plant/brake_engagements"),
        },
        "joint_limits": {
            "max_velocity_ratio": sim.pointer("/plant/max_velocity_ratio"),
            "velocity_limit_ticks": sim.pointer("/plant/velocity_limit_ticks"),
            "hard_stop_hits": sim.pointer("/plant/limit_hits"),
        },
        "rejected_messages": {
            "tracker": tr.get("rejected"),
            "sim_commands": sim.get("commands_rejected"),
            "goto_states": goto.get("states_rejected"),
        },
        "debris": if sc.has_debris() { json!({
            "scene": sc.debris.scene,
            "collision": collision.is_some(),
            "min_distance_m": sim.pointer("/debris/min_distance_m"),
            "contact_ticks": sim.pointer("/debris/contact_ticks"),
            "first_contact": sim.pointer("/debris/first_contact"),
            "observation_frames": sim.pointer("/debris/observation_frames"),
        }) } else { Value::Null },
        "camera": if sc.camera_on() { json!({
            "rate_hz": sc.camera.rate_hz,
            "frames": sim.pointer("/camera/stats/delivered"),
            "captured": sim.pointer("/camera/stats/captured"),
            "overrun": sim.pointer("/camera/stats/overrun"),
            "render_us": pick(sim.pointer("/camera/render_us").unwrap_or(&Value::Null), &["p50", "p99", "max"]),
        }) } else { Value::Null },
        "predictor": if sc.has_debris() { json!({
            // The scenario's method, also when the process left no statistics.
            "method": pred.get("method").cloned().unwrap_or_else(|| json!(sc.predictor_method())),
            "forecasts": pred.get("forecasts"),
            "forecast_rate_hz": pred.get("forecast_rate_hz"),
            "forecast_compute_us": pick(pred.get("forecast_compute_us").unwrap_or(&Value::Null), &["p50", "p99", "max"]),
            "tracks": pred.get("tracks"),
            "rejected_observations": pred.get("rejected_observations"),
            "fit_s": pred.get("fit_s"),
        }) } else { Value::Null },
        "planner": if planner { json!({
            "method": sc.planner.method,
            "cycles": plan.get("cycles"),
            "replans": plan.get("replans"),
            "plan_ms": pick(plan.get("plan_ms").unwrap_or(&Value::Null), &["p50", "p99", "max"]),
            "first_plan_ms": plan.get("first_plan_ms"),
            "deadline_misses": plan.get("deadline_misses"),
            "fallbacks": plan.get("fallbacks"),
            "min_predicted_clearance_m": plan.get("min_predicted_clearance_m"),
            "clearance_measured_up_to_m": plan.get("clearance_measured_up_to_m"),
            "cycles_waiting_for_forecast": plan.get("cycles_waiting_for_forecast"),
            "goal_reached_s": plan.get("goal_reached_s"),
        }) } else { Value::Null },
        "processes": procs.iter().map(status_json).collect::<Vec<_>>(),
        "driver": driver,
        "link": link,
        "rogue_nodes": ending.rogue,
        "goal_cli_pids": visitors,
        "restarts": restarts,
        "recording": opts.record.as_ref().map(|f| json!({
            "file": f.display().to_string(),
            "recorder": stats_of("recorder"),
        })),
        "sim": sim,
        "tracker": tr,
        "goto": goto,
        "predictor_stats": pred,
        "planner_stats": plan,
    });
    let mut report = report;
    // Nothing of the run is lost: a failed figure is noted in the report, a report that cannot
    // be written is printed instead.
    if let Some(f) = &opts.figures {
        match run_figures(&sc, &dir, f) {
            Ok(files) => {
                report["figures"] = json!(files.iter().map(|p| p.display().to_string()).collect::<Vec<_>>())
            }
            Err(e) => {
                eprintln!("dkrrt: {e}");
                report["figures_error"] = json!(e);
            }
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    let text = serde_json::to_string_pretty(&report).map_err(|e| e.to_string())?;
    if let Err(e) = std::fs::write(&opts.report, &text) {
        println!("{}", summary(&report));
        println!("{text}");
        return Err(format!("write report {}: {e} (the report is printed above)", opts.report.display()));
    }
    Ok((report, ok))
}

/// The short human summary printed after a run.
pub fn summary(r: &Value) -> String {
    let f = |p: &str| r.pointer(p).and_then(Value::as_f64).map_or("n/a".to_string(), |v| format!("{v:.1}"));
    let e = |p: &str| r.pointer(p).and_then(Value::as_f64).map_or("n/a".to_string(), |v| format!("{v:.2e}"));
    let mut s = String::new();
    s += &format!(
        "dkrrt run {} ({}, {:?}): {}\n",
        r["run_id"].as_str().unwrap_or("?"),
        r["scenario"].as_str().unwrap_or("?"),
        r["mode"].as_str().unwrap_or("?"),
        r["stop_reason"].as_str().unwrap_or("?")
    );
    s += &format!(
        "  ticks {}   deadline misses {}   plant time {} s   wall {} s\n",
        r["ticks"],
        r["deadline_misses"],
        f("/duration_s"),
        f("/wall_time_s")
    );
    s += &format!(
        "  wake latency us      p50 {}  p99 {}  p99.9 {}  max {}\n",
        f("/wake_latency_us/p50"),
        f("/wake_latency_us/p99"),
        f("/wake_latency_us/p999"),
        f("/wake_latency_us/max")
    );
    s += &format!(
        "  tick compute us      p50 {}  p99 {}  max {}\n",
        f("/tick_compute_us/p50"),
        f("/tick_compute_us/p99"),
        f("/tick_compute_us/max")
    );
    s += &format!(
        "  state->command us    p50 {}  p99 {}  max {}\n",
        f("/state_to_command_us/p50"),
        f("/state_to_command_us/p99"),
        f("/state_to_command_us/max")
    );
    s += &format!(
        "  tracking error rad   rms {}  max {}   final {}\n",
        e("/tracking_error_rad/rms"),
        e("/tracking_error_rad/max"),
        e("/final_error_rad")
    );
    if !r["camera"].is_null() {
        s += &format!(
            "  camera               frames {} at {} Hz on dkrrt/depth_image   render us p50 {} p99 {} max {}\n",
            r["camera"]["frames"],
            r["camera"]["rate_hz"],
            f("/camera/render_us/p50"),
            f("/camera/render_us/p99"),
            f("/camera/render_us/max")
        );
    }
    if !r["debris"].is_null() {
        s += &format!(
            "  debris ({})         min distance {} m   collision {}\n",
            r["debris"]["scene"].as_str().unwrap_or("?"),
            r.pointer("/debris/min_distance_m")
                .and_then(Value::as_f64)
                .map_or("n/a".into(), |v| format!("{v:.3}")),
            r["debris"]["collision"]
        );
        let method = r["predictor"]["method"].as_str().unwrap_or("?");
        if r["predictor"]["forecasts"].is_null() {
            s += &format!("  predictor ({method})  no statistics (the process did not finish)\n");
        } else {
            s += &format!(
                "  predictor ({method})  forecasts {} at {} Hz   compute us p50 {} p99 {}   rejected obs {}   frames lost {}\n",
                r["predictor"]["forecasts"],
                f("/predictor/forecast_rate_hz"),
                f("/predictor/forecast_compute_us/p50"),
                f("/predictor/forecast_compute_us/p99"),
                r["predictor"]["rejected_observations"],
                r.pointer("/predictor_stats/observations/frames_lost").map_or("n/a".into(), |v| v.to_string())
            );
        }
    }
    if !r["planner"].is_null() {
        let fb = &r["planner"]["fallbacks"];
        s += &format!(
            "  planner ({})  cycles {}  replans {}  plan ms p50 {} p99 {} max {}  deadline misses {}  fallbacks keep {} escape {} dodge {} brake {}\n",
            r["planner"]["method"].as_str().unwrap_or("?"),
            r["planner"]["cycles"],
            r["planner"]["replans"],
            f("/planner/plan_ms/p50"),
            f("/planner/plan_ms/p99"),
            f("/planner/plan_ms/max"),
            r["planner"]["deadline_misses"],
            fb["keep"],
            fb["escape"],
            fb["dodge"],
            fb["brake"],
        );
        s += &format!(
            "  planner              min predicted clearance {} m   goal reached at {} s\n",
            r.pointer("/planner/min_predicted_clearance_m").and_then(Value::as_f64).map_or(
                "n/a".into(),
                |v| {
                    // Measured up to the planner's cap: at the cap, that much or more.
                    let cap = r.pointer("/planner/clearance_measured_up_to_m").and_then(Value::as_f64);
                    if cap.is_some_and(|c| v >= c) {
                        format!(">= {v:.3}")
                    } else {
                        format!("{v:.3}")
                    }
                }
            ),
            r.pointer("/planner/goal_reached_s")
                .and_then(Value::as_f64)
                .map_or("never".into(), |v| format!("{v:.2}")),
        );
        let waited = r.pointer("/planner/cycles_waiting_for_forecast").and_then(Value::as_u64).unwrap_or(0);
        let cycles = r.pointer("/planner/cycles").and_then(Value::as_u64).unwrap_or(0);
        if waited > 0 && waited == cycles {
            s += "  planner              no forecast ever came: it planned no motion\n";
        } else if waited > 0 {
            s += &format!("  planner              {waited} cycles waited for a first forecast\n");
        }
    }
    s += &format!("  safe-hold entries {}", r["safe_hold"]["entries"]);
    if let Some(v) = r["final_velocity_rad_s"].as_array() {
        let vmax = v.iter().filter_map(Value::as_f64).fold(0.0f64, |m, x| m.max(x.abs()));
        s += &format!("   final joint speed {vmax:.1e} rad/s");
    }
    if r["link"].is_object() {
        let l = &r["link"];
        s += &format!(
            "\n  link (udp, delay {} ms, loss {}): round trip us p50 {} p99 {} max {}   states lost {} late {} dup {}   commands lost {} late {}   invalid {}   aborts {}",
            l["impairment"]["delay_ms"],
            l["impairment"]["loss"],
            f("/link/round_trip_us/p50"),
            f("/link/round_trip_us/p99"),
            f("/link/round_trip_us/max"),
            l["states_lost"],
            l["states_late"],
            l["states_duplicated"],
            l["commands_lost"],
            l["commands_late"],
            l["invalid_datagrams"],
            l["aborts"]
        );
    }
    for rs in r["restarts"].as_array().into_iter().flatten() {
        s += &format!(
            "\n  restarted {} at {:.1} s (pid {} -> {})",
            rs["name"].as_str().unwrap_or("?"),
            rs["t_s"].as_f64().unwrap_or(0.0),
            rs["old_pid"],
            rs["new_pid"]
        );
    }
    match r["checks"].as_array() {
        Some(c) if c.iter().all(|c| c["ok"] == true) => {
            s += &format!("\n  verdict: ok ({} checks passed)", c.len())
        }
        Some(c) => {
            for c in c.iter().filter(|c| c["ok"] != true) {
                s += &format!(
                    "\n  FAILED check {}: {}",
                    c["name"].as_str().unwrap_or("?"),
                    c["detail"].as_str().unwrap_or("?")
                );
            }
        }
        None => {}
    }
    for p in r["processes"].as_array().into_iter().flatten() {
        s += &format!(
            "\n  {:<9} pid {:<7} exit {}{}",
            p["name"].as_str().unwrap_or("?"),
            p["pid"],
            p["exit_code"],
            if p["signal"].is_null() { String::new() } else { format!(" (signal {})", p["signal"]) }
        );
    }
    s
}

/// Fig. 2, Fig. 4 and the clearance plot of a process-set run, from the traces the tracker
/// (measured positions and its reference) and the sim (true distance, debris positions) wrote
/// into the run directory, with the planner's predicted clearance per cycle (when the source is
/// the planner).
fn run_figures(sc: &Scenario, run_dir: &Path, out: &Path) -> Result<Vec<PathBuf>, String> {
    let read = |name: &str| -> Result<Value, String> {
        let p = run_dir.join(format!("{name}-trace.json"));
        let t = std::fs::read_to_string(&p).map_err(|e| format!("--figures: {}: {e}", p.display()))?;
        serde_json::from_str(&t).map_err(|e| format!("--figures: {}: {e}", p.display()))
    };
    let (trk, sim) = (read("tracker")?, read("sim")?);
    let planned: Vec<(f64, f64)> = if sc.replans() {
        read("planner")?
            .as_array()
            .map_or(Vec::new(), |a| a.iter().filter_map(|e| Some((e[0].as_f64()?, e[1].as_f64()?))).collect())
    } else {
        Vec::new()
    };
    // The newest cycle's prediction at or before `t` (cycles are ≥ 10 ms apart).
    let predicted_at = |t: f64| {
        let i = planned.partition_point(|c| c.0 <= t + 1e-9);
        i.checked_sub(1).map(|i| planned[i]).filter(|c| t - c.0 < 0.25).map(|c| c.1)
    };
    let model = sc.load_arm().map_err(|e| e.to_string())?;
    let arr = |v: &Value| -> Option<[f64; 6]> {
        let a = v.as_array()?;
        (a.len() == 6).then(|| std::array::from_fn(|i| a[i].as_f64().unwrap_or(f64::NAN)))
    };
    let ee = |q: &[f64; 6]| {
        let x = model.fk(&dkrrt_model::JVec::from_row_slice(q)).translation.vector;
        [x[0], x[1], x[2]]
    };
    let dist: Vec<(f64, f64)> = sim["distance"]
        .as_array()
        .map(|a| a.iter().filter_map(|e| Some((e[0].as_f64()?, e[1].as_f64()?))).collect())
        .unwrap_or_default();
    let distance_at = |t: f64| {
        let i = dist.partition_point(|d| d.0 < t - 1e-9);
        dist.get(i).filter(|d| (d.0 - t).abs() < 0.02).map(|d| d.1)
    };
    let samples: Vec<crate::lockstep::TraceSample> = trk
        .as_array()
        .map(|a| a.as_slice())
        .unwrap_or(&[])
        .iter()
        .filter_map(|s| {
            let t_s = s["t_s"].as_f64()?;
            let q = arr(&s["q"])?;
            let q_des = arr(&s["q_des"]);
            Some(crate::lockstep::TraceSample {
                t_s,
                q,
                qd: [0.0; 6],
                q_des,
                qd_des: arr(&s["qd_des"]),
                qdd_des: arr(&s["qdd_des"]),
                ee: ee(&q),
                ee_des: q_des.map(|qd| ee(&qd)),
                true_distance_m: distance_at(t_s),
                predicted_clearance_m: predicted_at(t_s),
            })
        })
        .collect();
    let debris: Vec<(f64, u32, [f64; 3])> = sim["debris"]
        .as_array()
        .map(|a| {
            a.iter()
                .filter_map(|e| {
                    let p = e[2].as_array()?;
                    Some((
                        e[0].as_f64()?,
                        e[1].as_u64()? as u32,
                        [p[0].as_f64()?, p[1].as_f64()?, p[2].as_f64()?],
                    ))
                })
                .collect()
        })
        .unwrap_or_default();
    if samples.is_empty() {
        return Err("--figures: the tracker traced no state (did the run start?)".into());
    }
    let t = crate::figures::EpisodeTrace {
        scene: match (&sc.episode, sc.has_debris()) {
            (Some(e), _) => e.scene.clone(),
            (None, true) => sc.debris.scene.clone(),
            (None, false) => "no debris".into(),
        },
        episode: sc.episode.as_ref().map_or(0, |e| e.index),
        method: format!("{}, processes", sc.planner.method),
        samples,
        debris,
        v_max: sc.motion.v_max,
        a_max: sc.motion.a_max,
        j_max: sc.motion.j_max,
        margin_m: sc.planner.margin_m,
    };
    let mut files = Vec::new();
    files.extend(crate::figures::fig2(out, &t)?);
    files.extend(crate::figures::fig4(out, &t)?);
    files.extend(crate::figures::clearance(out, &t)?);
    Ok(files)
}

#[cfg(test)]
mod tests {
    use serde_json::json;

    /// The planner's predicted clearance is measured up to its cap: at the cap the summary
    /// says "that much or more", below it the figure.
    #[test]
    fn a_clearance_at_the_cap_is_printed_as_a_lower_bound() {
        let line = |m: f64| {
            let r = json!({"planner": {"min_predicted_clearance_m": m, "clearance_measured_up_to_m": 1.0}});
            let s = super::summary(&r);
            s.lines().find(|l| l.contains("min predicted clearance")).expect("the planner's line").to_string()
        };
        assert!(line(1.0).contains("min predicted clearance >= 1.000 m"), "{}", line(1.0));
        assert!(line(0.25).contains("min predicted clearance 0.250 m"), "{}", line(0.25));
        assert!(line(-0.02).contains("min predicted clearance -0.020 m"), "{}", line(-0.02));
    }

    /// A planner that never got a forecast says so (it planned no motion), and one that
    /// waited for its first says how long.
    #[test]
    fn cycles_waiting_for_a_forecast_are_reported() {
        let text = |waited: u64| {
            super::summary(&json!({"planner": {"cycles": 80, "cycles_waiting_for_forecast": waited}}))
        };
        assert!(text(80).contains("no forecast ever came: it planned no motion"), "{}", text(80));
        assert!(text(3).contains("3 cycles waited for a first forecast"), "{}", text(3));
        assert!(!text(0).contains("forecast"), "{}", text(0));
    }
}

//! `dkrrt faults`: the fault matrix. Each case launches the default run as a process set
//! (`dkrrt launch`, real time), does one thing to it at a random time — SIGKILL or SIGSTOP of
//! one process, NaN and out-of-range messages injected on one service, a rogue trajectory
//! source on the run, a report that cannot be written — and checks what the run must then
//! show: the arm safe and at rest, the failure named, bad messages rejected and counted, the
//! verdict not `ok`. One line per case (expected, observed, pass/fail); the command fails if
//! any case fails. Not a test: it takes minutes and depends on the machine's timing.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

use dkrrt_msg::bus::{Bus, Topic};
use dkrrt_msg::*;

/// One row of the matrix.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Outcome {
    pub case: String,
    pub expected: String,
    pub observed: String,
    pub pass: bool,
}

/// What is done to the run.
#[derive(Debug, Clone, Copy)]
enum Fault {
    Kill(&'static str),
    Stop(&'static str),
    Inject(Service),
    /// A second `goto` or `sim` started on the live run.
    Rogue(&'static str),
    ReportDiskFull,
}

#[derive(Debug, Clone, Copy)]
enum Service {
    RobotState,
    TorqueCommand,
    Trajectory,
    Goal,
    Observation,
    Forecast,
}

impl Service {
    fn name(self) -> &'static str {
        match self {
            Service::RobotState => RobotState::SERVICE,
            Service::TorqueCommand => TorqueCommand::SERVICE,
            Service::Trajectory => Trajectory::SERVICE,
            Service::Goal => Goal::SERVICE,
            Service::Observation => DebrisObservation::SERVICE,
            Service::Forecast => DebrisForecast::SERVICE,
        }
    }

    /// The report's count of rejected messages of this service (its reader), and the least
    /// of the injected ones that must be seen rejected (readers that poll slower than the
    /// publishers may lose some to their buffer, which is counted as lost, not rejected).
    fn rejected(self, r: &Value, injected: u64) -> (u64, u64) {
        let n = |p: &str| r.pointer(p).and_then(Value::as_u64).unwrap_or(0);
        match self {
            Service::RobotState => (n("/tracker/rejected/state"), injected),
            Service::TorqueCommand => (n("/sim/commands_rejected"), injected),
            Service::Trajectory => (n("/tracker/rejected/trajectory"), injected),
            Service::Goal => (n("/planner_stats/rejected"), injected),
            Service::Observation => (
                n("/predictor_stats/observations/frames_rejected")
                    + n("/predictor_stats/observations/items_invalid"),
                injected,
            ),
            // The planner reads forecasts once per cycle (10 Hz) from a 4-deep buffer while the
            // predictor publishes at 50 Hz: most injected ones are overwritten unread.
            Service::Forecast => (n("/planner_stats/rejected"), 1),
        }
    }
}

fn cases() -> Vec<Fault> {
    let mut v = Vec::new();
    // goto: on a run of the straight source without debris (the default runs the planner).
    for p in ["sim", "predictor", "tracker", "planner", "goto"] {
        v.push(Fault::Kill(p));
    }
    for p in ["sim", "predictor", "tracker", "planner", "goto"] {
        v.push(Fault::Stop(p));
    }
    for s in [
        Service::RobotState,
        Service::TorqueCommand,
        Service::Trajectory,
        Service::Goal,
        Service::Observation,
        Service::Forecast,
    ] {
        v.push(Fault::Inject(s));
    }
    v.push(Fault::Rogue("goto"));
    v.push(Fault::Rogue("sim"));
    v.push(Fault::ReportDiskFull);
    v
}

fn describe(f: Fault) -> (String, String) {
    match f {
        Fault::Kill(p) | Fault::Stop(p) => {
            let how = if matches!(f, Fault::Kill(_)) { "kill -9" } else { "SIGSTOP" };
            let then = match p {
                "sim" => "tracker safe hold, run fails naming sim",
                "tracker" => "plant brakes, arm at rest, run fails naming tracker",
                "goto" => "tracker finishes (or brakes on) its trajectory, run goes on to its end, arm at rest, run fails naming goto",
                _ => "restarted, run goes on to its end, arm at rest, run fails naming it",
            };
            (format!("{how} {p}"), then.to_string())
        }
        Fault::Inject(s) => (
            match s {
                Service::Observation | Service::Forecast => {
                    format!("NaN/out-of-range/stamped 1000 s ahead on {}", s.name())
                }
                _ => format!("NaN/out-of-range on {}", s.name()),
            },
            "rejected and counted, arm at rest within limits, run not ok".into(),
        ),
        Fault::Rogue(p) => (
            format!("rogue {p} on the live run"),
            format!(
                "rogue node reported, its {} ignored by the tracker, arm at rest, run not ok",
                if p == "sim" { "robot states" } else { "trajectories" }
            ),
        ),
        Fault::ReportDiskFull => (
            "report on a full disk (/dev/full)".into(),
            "exit non-zero naming the report, report printed instead, arm at rest".into(),
        ),
    }
}

/// A launched run: the launcher child and its processes' pids.
struct Launched {
    child: Child,
    pids: Vec<(String, i32)>,
    out: std::thread::JoinHandle<String>,
}

fn start(
    exe: &Path,
    run: &str,
    scenario: &Path,
    duration: f64,
    report: &Path,
    stderr: &Path,
) -> Result<Launched, String> {
    let err = std::fs::File::create(stderr).map_err(|e| format!("{}: {e}", stderr.display()))?;
    let mut child = Command::new(exe)
        .args(["launch", "--run", run, "--duration", &duration.to_string(), "--scenario"])
        .arg(scenario)
        .arg("--report")
        .arg(report)
        .stdout(Stdio::piped())
        .stderr(err)
        .stdin(Stdio::null())
        .spawn()
        .map_err(|e| format!("start launch: {e}"))?;
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let mut pids = Vec::new();
    let mut alive = false;
    for line in lines.by_ref() {
        let line = line.map_err(|e| e.to_string())?;
        if let Some((name, pid)) = line.strip_prefix("dkrrt: started ").and_then(|r| r.split_once(" pid ")) {
            pids.push((name.to_string(), pid.trim().parse::<i32>().unwrap_or(0)));
        }
        if line.starts_with("dkrrt: all processes alive") {
            alive = true;
            break;
        }
    }
    let out = std::thread::spawn(move || lines.map_while(Result::ok).collect::<Vec<_>>().join("\n"));
    if !alive {
        let _ = child.kill();
        return Err("the run did not come up".into());
    }
    Ok(Launched { child, pids, out })
}

fn pid_of(pids: &[(String, i32)], name: &str) -> Result<i32, String> {
    pids.iter().find(|p| p.0 == name).map(|p| p.1).ok_or_else(|| format!("no {name} in the run"))
}

fn signal(pid: i32, sig: i32) -> Result<(), String> {
    // SAFETY: kill(2) on a pid the launcher reported for this case's run.
    if unsafe { libc::kill(pid, sig) } == 0 {
        Ok(())
    } else {
        Err(format!("kill({pid}, {sig}): {}", std::io::Error::last_os_error()))
    }
}

/// Publishes `n` bad messages (alternately a NaN and an out-of-range value) on `s`, 200 ms
/// apart. Returns how many were sent.
fn inject(run: &str, s: Service, n: u64) -> Result<u64, String> {
    let bus = Bus::new(run, "injector").map_err(|e| e.to_string())?;
    let e = |e: dkrrt_msg::bus::BusError| e.to_string();
    macro_rules! send {
        ($t:ty, $src:expr, $bad:expr) => {{
            let mut p = bus.publisher::<$t>($src).map_err(e)?;
            let mut m = Box::new(<$t as Zeroed>::zeroed());
            for i in 0..n {
                let f: &dyn Fn(&mut $t, u64) = &$bad;
                f(&mut m, i);
                p.publish(&mut m).map_err(e)?;
                std::thread::sleep(Duration::from_millis(200));
            }
        }};
    }
    // NaN and out-of-range values in turn.
    let bad = |i: u64| if i.is_multiple_of(2) { f64::NAN } else { 1e6 };
    match s {
        Service::RobotState => send!(RobotState, Source::Sim, |m: &mut RobotState, i| m.q[0] = bad(i)),
        Service::TorqueCommand => {
            send!(TorqueCommand, Source::Tracker, |m: &mut TorqueCommand, i| { m.tau[0] = bad(i) })
        }
        Service::Trajectory => send!(Trajectory, Source::Planner, |m: &mut Trajectory, i| {
            m.traj_id = 999;
            m.n_seg = [1; 6];
            m.duration_s = 1.0;
            m.seg[0][0].p = bad(i);
        }),
        Service::Goal => send!(Goal, Source::User, |m: &mut Goal, i| {
            m.kind = 0;
            m.q[2] = bad(i)
        }),
        // Every third: a plausible pose of a new object, stamped 1000 s ahead of the plant
        // clock (it would age every track out).
        Service::Observation => send!(DebrisObservation, Source::Sim, |m: &mut DebrisObservation, i| {
            m.count = 1;
            m.items[0].q = [1.0, 0.0, 0.0, 0.0];
            if i % 3 == 2 {
                (m.items[0].id, m.items[0].p, m.items[0].bounding_radius) = (999, [3.0, 0.0, 0.0], 0.2);
                m.header.stamp_ns = 1_000_000_000_000;
                m.items[0].t_meas_ns = 1_000_000_000_000;
            } else {
                m.items[0].p = [bad(i), 0.0, 0.0];
                (m.header.stamp_ns, m.items[0].t_meas_ns) = (0, 0);
            }
        }),
        Service::Forecast => send!(DebrisForecast, Source::Predictor, |m: &mut DebrisForecast, i| {
            m.count = 1;
            m.steps = 1;
            m.dt_s = 0.1;
            m.tracks[0].steps[0].q = [1.0, 0.0, 0.0, 0.0];
            // Every third: a plausible forecast stamped 1000 s ahead of the plant clock.
            if i % 3 == 2 {
                m.t0_ns = 1_000_000_000_000;
                m.tracks[0].steps[0].p = [3.0, 0.0, 0.0];
            } else {
                m.t0_ns = 0;
                m.tracks[0].steps[0].p = [bad(i), 0.0, 0.0];
            }
        }),
    }
    Ok(n)
}

fn read_report(p: &Path) -> Result<Value, String> {
    let t = std::fs::read_to_string(p).map_err(|e| format!("report {}: {e}", p.display()))?;
    serde_json::from_str(&t).map_err(|e| format!("report {}: {e}", p.display()))
}

fn final_speed(r: &Value) -> Option<f64> {
    let v = r["final_velocity_rad_s"].as_array()?;
    Some(v.iter().filter_map(Value::as_f64).fold(0.0, |m, x| m.max(x.abs())))
}

fn failed_checks(r: &Value) -> String {
    r["failed_checks"]
        .as_array()
        .map_or(String::new(), |a| a.iter().filter_map(Value::as_str).collect::<Vec<_>>().join(","))
}

fn has_failed(r: &Value, check: &str) -> bool {
    r["failed_checks"].as_array().is_some_and(|a| a.iter().any(|c| c == check))
}

/// The default scenario without its threat episode and debris, with the straight source
/// (`dkrrt goto`): sim.initial_q to goal.q.
fn straight_scenario() -> Result<String, String> {
    let text = dkrrt_config::DEFAULT_SCENARIO;
    let i = text.find("\n[episode]").ok_or("the default scenario has no [episode]")? + 1;
    let j = i + text[i..].find("\n[debris]").ok_or("no [debris] after [episode]")?;
    let out = format!("{}{}", &text[..i], &text[j + 1..])
        .replacen("method = \"dk-rrt\"", "method = \"straight\"", 1)
        .replacen("scene = \"sparse-slow\"", "scene = \"\"", 1);
    let sc = dkrrt_config::Scenario::from_toml_str(&out, "straight scenario").map_err(|e| e.to_string())?;
    if sc.planner.method != "straight" || sc.has_debris() {
        return Err("the straight scenario still has the planner or debris".into());
    }
    Ok(out)
}

/// Runs one case; returns (observed, pass).
fn run_case(exe: &Path, dir: &Path, i: usize, f: Fault, rng: &mut u64) -> Result<(String, bool), String> {
    let run = format!("faults-{}-{i}", crate::launch::random_hex(4));
    let report = if matches!(f, Fault::ReportDiskFull) {
        PathBuf::from("/dev/full")
    } else {
        dir.join(format!("case{i}.json"))
    };
    let duration = 6.0;
    let err_path = dir.join(format!("case{i}.stderr"));
    let scenario = match f {
        Fault::Kill("goto") | Fault::Stop("goto") => {
            let p = dir.join(format!("case{i}-straight.toml"));
            crate::launch::write_private(&p, &straight_scenario()?)?;
            p
        }
        _ => PathBuf::from("default"),
    };
    let mut l = start(exe, &run, &scenario, duration, &report, &err_path)?;
    // A random time in [1.0, 3.0) s into the run (mid-motion).
    *rng ^= *rng << 13;
    *rng ^= *rng >> 7;
    *rng ^= *rng << 17;
    let at = 1.0 + (*rng % 2000) as f64 * 1e-3;
    std::thread::sleep(Duration::from_secs_f64(at));
    let t0 = Instant::now();
    let mut injected = 0;
    let mut rogue: Option<Child> = None;
    match f {
        Fault::Kill(p) => signal(pid_of(&l.pids, p)?, libc::SIGKILL)?,
        Fault::Stop(p) => signal(pid_of(&l.pids, p)?, libc::SIGSTOP)?,
        Fault::Inject(s) => injected = inject(&run, s, 10)?,
        Fault::Rogue(p) => {
            let mut cmd = Command::new(exe);
            match p {
                "sim" => cmd.args(["sim", "--run", &run]),
                _ => cmd.args(["goto", "--run", &run, "--goal", "0.1,0.1,0.1,0.1,0.1,0.1"]),
            };
            rogue = Some(
                cmd.stdout(Stdio::null())
                    .stderr(Stdio::null())
                    .spawn()
                    .map_err(|e| format!("start rogue {p}: {e}"))?,
            );
        }
        Fault::ReportDiskFull => {}
    }
    let status = l.child.wait().map_err(|e| e.to_string())?;
    let Launched { pids, out, .. } = l;
    let out = out.join().unwrap_or_default();
    if let Some(mut g) = rogue {
        let _ = g.kill();
        let _ = g.wait();
    }
    if let Fault::Stop(p) = f {
        // Whatever is left of the stopped process (the launcher SIGKILLs it): let it go.
        let _ = pid_of(&pids, p).map(|pid| signal(pid, libc::SIGCONT));
    }
    let wall = t0.elapsed().as_secs_f64();
    let r = if matches!(f, Fault::ReportDiskFull) {
        // The report is printed on stdout after the summary.
        let start = out.find("\n{").map(|i| i + 1).ok_or("no report printed")?;
        serde_json::from_str::<Value>(&out[start..]).map_err(|e| format!("printed report: {e}"))?
    } else {
        read_report(&report)?
    };
    let stderr = std::fs::read_to_string(&err_path).unwrap_or_default();
    let speed = final_speed(&r);
    let rest = speed.is_some_and(|v| v < 1e-3);
    let limits =
        r.pointer("/joint_limits/max_velocity_ratio").and_then(Value::as_f64).is_some_and(|x| x <= 1.0)
            && r.pointer("/joint_limits/hard_stop_hits").and_then(Value::as_u64) == Some(0);
    let reason = r["stop_reason"].as_str().unwrap_or("").to_string();
    let dur = r["duration_s"].as_f64().unwrap_or(0.0);
    let not_ok = r["ok"] == false && !status.success();
    let speed_s = speed.map_or("n/a".into(), |v| format!("{v:.1e}"));
    let base = format!(
        "ok={} exit={} final speed {speed_s} rad/s, {dur:.2} s plant time, failed [{}]",
        r["ok"],
        status.code().map_or("signal".into(), |c| c.to_string()),
        failed_checks(&r)
    );
    Ok(match f {
        Fault::Kill(p) | Fault::Stop(p) => {
            let named = reason.contains(p);
            let ok = match p {
                "sim" => {
                    let hold = r["safe_hold"]["events"]
                        .as_array()
                        .is_some_and(|e| e.iter().any(|e| e["reason"] == "stale_state"));
                    not_ok && named && hold
                }
                "goto" => {
                    // The trajectory was out before the fault: the tracker finishes it, or
                    // brakes on it if the machine stalls it into a safe hold (goto never
                    // restarts, so nothing re-plans): the run goes on to its end either way.
                    not_ok && named && rest && limits && dur >= duration - 1e-9
                }
                "tracker" => {
                    let brakes =
                        r.pointer("/safe_hold/plant_brake_engagements").and_then(Value::as_u64).unwrap_or(0);
                    not_ok && named && brakes >= 1 && rest && limits
                }
                _ => {
                    let restarted =
                        r["restarts"].as_array().is_some_and(|a| a.iter().any(|x| x["name"] == p));
                    not_ok
                        && named
                        && restarted
                        && rest
                        && limits
                        && dur >= duration - 1e-9
                        && r["debris"]["collision"] == false
                }
            };
            let restarts = r["restarts"].as_array().map_or(0, Vec::len);
            let goal = if p == "goto" {
                let holds = r.pointer("/safe_hold/entries").and_then(Value::as_u64).unwrap_or(0);
                let goal = if has_failed(&r, "goal_reached") { "not reached" } else { "reached" };
                format!("; goal {goal}, {holds} safe hold(s)")
            } else {
                String::new()
            };
            (format!("{base}; {restarts} restart(s){goal}; reason: {reason}"), ok)
        }
        Fault::Inject(s) => {
            let (rejected, need) = s.rejected(&r, injected);
            let ok = not_ok && rest && limits && rejected >= need && has_failed(&r, "rejected_messages");
            (format!("{base}; {rejected} of {injected} injected rejected (need {need})"), ok)
        }
        Fault::Rogue(p) => {
            let (field, what) = if p == "sim" {
                ("foreign_states", "robot states")
            } else {
                ("foreign_trajectories", "trajectories")
            };
            let foreign = r.pointer(&format!("/tracker/{field}")).and_then(Value::as_u64).unwrap_or(0);
            let listed = r["rogue_nodes"]
                .as_array()
                .is_some_and(|a| a.iter().any(|n| n.as_str().is_some_and(|s| s.starts_with(p))));
            let ok =
                not_ok && rest && limits && foreign >= 1 && listed && has_failed(&r, "no_rogue_publishers");
            (format!("{base}; rogue listed {listed}, {foreign} foreign {what} ignored"), ok)
        }
        Fault::ReportDiskFull => {
            let named = stderr.contains("write report /dev/full");
            let ok = !status.success() && status.code() == Some(2) && rest && named;
            (format!("{base}; error names the report: {named}; {wall:.1} s"), ok)
        }
    })
}

/// Runs the matrix; prints one line per case; returns the outcomes.
pub fn run(only: Option<&str>) -> Result<Vec<Outcome>, String> {
    if let Some(o) = only {
        let names: Vec<String> = cases().into_iter().map(|f| describe(f).0).collect();
        if !names.iter().any(|n| n.contains(o)) {
            return Err(format!("--only {o:?}: no case's name contains it (cases: {})", names.join(", ")));
        }
    }
    let exe = std::env::current_exe().map_err(|e| e.to_string())?;
    let dir = crate::launch::private_dir("faults")?;
    let mut rng = u64::from_str_radix(&crate::launch::random_hex(8), 16).unwrap_or(0x9e37_79b9_7f4a_7c15) | 1;
    let mut out = Vec::new();
    println!("{:<40} {:<75} {:<6} observed", "case", "expected", "result");
    for (i, f) in cases().into_iter().enumerate() {
        let (case, expected) = describe(f);
        if only.is_some_and(|o| !case.contains(o)) {
            continue;
        }
        let (observed, pass) = match run_case(&exe, &dir, i, f, &mut rng) {
            Ok(x) => x,
            Err(e) => (format!("error: {e}"), false),
        };
        println!("{case:<40} {expected:<75} {:<6} {observed}", if pass { "pass" } else { "FAIL" });
        if pass {
            for name in [format!("case{i}.json"), format!("case{i}.stderr"), format!("case{i}-straight.toml")]
            {
                let _ = std::fs::remove_file(dir.join(name));
            }
        }
        out.push(Outcome { case, expected, observed, pass });
    }
    let failed = out.iter().filter(|o| !o.pass).count();
    if failed == 0 {
        let _ = std::fs::remove_dir_all(&dir);
    } else {
        // The evidence: each case's report (caseN.json) and the launcher's stderr.
        eprintln!("faults: reports and logs of the cases kept in {}", dir.display());
    }
    println!(
        "faults: {} of {} cases pass{}",
        out.len() - failed,
        out.len(),
        if failed > 0 { "; FAILED" } else { "" }
    );
    Ok(out)
}

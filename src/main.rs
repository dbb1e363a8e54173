//! The `dkrrt` command line.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};
use dkrrt::launch::{launch, summary, Driver, LaunchOptions};
use dkrrt_config::{Mode, Scenario};

#[derive(Parser)]
#[command(
    name = "dkrrt",
    version,
    about = "Deep Koopman RRT: real-time space-manipulator motion through moving debris"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Args, Clone)]
struct Common {
    /// Scenario TOML file, or "default" for the embedded default scenario.
    #[arg(long, default_value = "default")]
    scenario: String,
    /// Override the scenario's run mode.
    #[arg(long, value_parser = ["realtime", "lockstep"])]
    mode: Option<String>,
    /// Override the scenario's duration (plant seconds).
    #[arg(long)]
    duration: Option<f64>,
}

#[derive(Args)]
struct ProcArgs {
    #[command(flatten)]
    common: Common,
    /// Run id: processes of one run share it; different runs never see each other.
    #[arg(long, default_value = "default")]
    run: String,
    /// Write this process's statistics as JSON here at exit.
    #[arg(long)]
    stats: Option<PathBuf>,
    /// Keep a trace and write it as JSON here at exit (sim and tracker every 10 ms, the planner
    /// every cycle; the launcher's `--figures` uses them).
    #[arg(long)]
    trace: Option<PathBuf>,
}

#[derive(Subcommand)]
enum Cmd {
    /// Start sim, predictor, tracker and the trajectory source as separate processes, supervise them, report.
    Launch {
        #[command(flatten)]
        common: Common,
        /// Where to write the JSON report.
        #[arg(long, default_value = "dkrrt-report.json")]
        report: PathBuf,
        /// Run id (default: generated, unique per launch).
        #[arg(long)]
        run: Option<String>,
        /// Record every service of the run into this MCAP file (a separate recorder process).
        #[arg(long)]
        record: Option<PathBuf>,
        /// Draw the run's figures here: the end effector's desired vs real path with the
        /// debris (Fig. 2), joint velocity/acceleration/jerk against the limits (Fig. 4), the
        /// true clearance over time (SVG and PNG).
        #[arg(long)]
        figures: Option<PathBuf>,
        /// The arm's driver: `sim` (the plant simulator on the bus) or `udp` (hardware in the
        /// loop: `dkrrt udp-driver` talking to `dkrrt arm-emulator` over UDP on loopback, with
        /// the scenario's `[udp]` delay, jitter, loss, duplication and reordering).
        #[arg(long, default_value = "sim", value_parser = ["sim", "udp"])]
        driver: String,
    },
    /// The latency and jitter suite: a cyclictest-style baseline thread, the tracker's wake-up
    /// and state->command latency in the real process set, and an iceoryx2 ping-pong per message
    /// type through dkrrt's bus and through raw iceoryx2, side by side; percentiles, JSON and
    /// percentile plots into --out.
    Latency {
        #[command(flatten)]
        common: Common,
        /// Load beside the measurement: none, cpu (a busy thread per core) or io (4 MiB writes
        /// with fsync).
        #[arg(long, default_value = "none", value_parser = ["none", "cpu", "io"])]
        load: String,
        /// Directory for latency.json and the figures.
        #[arg(long, default_value = "dkrrt-latency")]
        out: PathBuf,
    },
    /// The echo side of `dkrrt latency`'s ping-pong (started by it).
    #[command(hide = true)]
    LatencyEcho {
        #[command(flatten)]
        common: Common,
        #[arg(long)]
        ping_run: String,
        #[arg(long)]
        pong_run: String,
        #[arg(long, default_value_t = 60.0)]
        seconds: f64,
        #[arg(long)]
        stats: PathBuf,
    },
    /// The network arm driver: takes the simulator's place on the bus and talks to an arm over
    /// dkrrt's UDP protocol (docs/udp-protocol.md).
    UdpDriver {
        #[command(flatten)]
        p: ProcArgs,
        /// The driver's UDP address (the arm sends its states here).
        #[arg(long, default_value = "127.0.0.1:50001")]
        listen: std::net::SocketAddr,
        /// The arm's UDP address (commands go there).
        #[arg(long, default_value = "127.0.0.1:50002")]
        arm: std::net::SocketAddr,
    },
    /// The arm emulator ("hardware" for HIL runs): the simulated plant behind the UDP protocol on
    /// its own 1 kHz clock, with the scenario's `[udp]` network impairments; runs until SIGTERM.
    ArmEmulator {
        #[command(flatten)]
        common: Common,
        /// The arm's UDP address (commands arrive here).
        #[arg(long, default_value = "127.0.0.1:50002")]
        listen: std::net::SocketAddr,
        /// The driver's UDP address (states go there).
        #[arg(long, default_value = "127.0.0.1:50001")]
        driver: std::net::SocketAddr,
        /// Write the emulator's statistics as JSON here at exit.
        #[arg(long)]
        stats: Option<PathBuf>,
    },
    /// The plant simulator process: integrates the arm under commanded torques, publishes state at 1 kHz.
    Sim {
        #[command(flatten)]
        p: ProcArgs,
        /// Lockstep only: hold at tick 0 until a trajectory has been published.
        #[arg(long)]
        gate_trajectory: bool,
        /// Lockstep with debris only: hold at tick 0 until the debris observations have a reader.
        #[arg(long)]
        gate_predictor: bool,
        /// Lockstep with the DK-RRT planner: hold at each planner cycle until its status is out.
        #[arg(long)]
        gate_planner: bool,
    },
    /// The 1 kHz computed-torque tracker process.
    Tracker(ProcArgs),
    /// The trajectory source: plans a jerk-limited trajectory to a joint goal and publishes it.
    Goto {
        #[command(flatten)]
        p: ProcArgs,
        /// Joint goal in rad: six numbers, comma or space separated (default: the scenario's goal).
        #[arg(long, value_delimiter = ',', num_args = 1..=6, allow_negative_numbers = true)]
        goal: Option<Vec<f64>>,
    },
    /// The anytime DK-RRT planner: replans against the debris forecasts, publishes spliced trajectories.
    Planner {
        #[command(flatten)]
        p: ProcArgs,
        /// How many times the launcher has restarted this planner in the run (its trajectory
        /// ids start at restart × 1 000 000 + 1).
        #[arg(long, default_value_t = 0)]
        restart: u32,
        /// Joint goal in rad: six numbers, comma or space separated (default: the scenario's goal).
        #[arg(long, value_delimiter = ',', num_args = 1..=6, allow_negative_numbers = true)]
        goal: Option<Vec<f64>>,
    },
    /// Send a goal to the trajectory source of a live run: joint positions or an end-effector pose.
    Goal {
        #[command(flatten)]
        common: Common,
        /// Run id of the live run.
        #[arg(long, default_value = "default")]
        run: String,
        /// Joint goal in rad, comma separated.
        #[arg(long, value_delimiter = ',', allow_negative_numbers = true, conflicts_with = "pose")]
        q: Option<Vec<f64>>,
        /// End-effector pose in the base frame: x,y,z (m), qw,qx,qy,qz (unit quaternion).
        #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
        pose: Option<Vec<f64>>,
        /// Wait this long for a goto or planner to subscribe, s.
        #[arg(long, default_value_t = 5.0)]
        wait: f64,
    },
    /// The debris predictor process: tracks debris observations, publishes Koopman forecasts (>= 50 Hz).
    Predictor(ProcArgs),
    /// Record the debris observations of a run (a sensor's or the sim's) to a file for `train --observations`.
    Record {
        #[command(flatten)]
        common: Common,
        /// Run id to listen on.
        #[arg(long, default_value = "default")]
        run: String,
        /// File to write (JSON lines, one observation item per line; format: planner/predictor/README.md).
        #[arg(long)]
        out: PathBuf,
        /// Stop after this many wall-clock seconds (default: at the end of the run, or Ctrl-C).
        #[arg(long, value_parser = seconds_arg)]
        seconds: Option<f64>,
    },
    /// Train the Deep Koopman debris model on simulated debris-world data (or recorded observations) and save the model file.
    Train {
        /// Model file to write (default: deep-attitude.dkm; with --visual, visual.dkv; formats:
        /// planner/deep/README.md, planner/visual/src/file.rs).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Train the learned visual features f_θ on depth-camera views (Algorithm 1) instead
        /// of the deep attitude model.
        #[arg(long, conflicts_with_all = ["observations", "json"])]
        visual: bool,
        /// Seconds-scale training (tiny network, little data) for smoke tests.
        #[arg(long)]
        quick: bool,
        /// Override the number of epochs.
        #[arg(long)]
        epochs: Option<usize>,
        /// Also write the validation table (and training report) as JSON here.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Train on these recorded observation files (`dkrrt record`) instead of simulated data.
        #[arg(long, value_delimiter = ',')]
        observations: Option<Vec<PathBuf>>,
        /// With --observations: the scenario whose sensor noise and orbit (debris scene) apply.
        #[arg(long, default_value = "default")]
        scenario: String,
    },
    /// Accuracy study of the debris predictors: median errors at 0.5/1/2/4 s on held-out runs of every scene.
    PredictEval {
        /// Write the rows {scene, method, horizon_s, pos_err_m, att_err_rad, n} as JSON here.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Study size: small (seconds), medium (the README table), full.
        #[arg(long, default_value = "medium", value_parser = ["small", "medium", "full"])]
        size: String,
        /// Deep model file (default: the model embedded in the binary; "train" = train one first).
        #[arg(long)]
        model: Option<String>,
        /// Comma-separated scenes (default: all four).
        #[arg(long, value_delimiter = ',')]
        scenes: Option<Vec<String>>,
        /// Comma-separated methods (default: all).
        #[arg(long, value_delimiter = ',')]
        methods: Option<Vec<String>>,
        /// Master seed of the study's runs (training `seed + i`, held-out `seed + 1000 + i`,
        /// per scene offsets); another seed = another independent set of runs.
        #[arg(long, default_value_t = 7)]
        seed: u64,
        /// The learned visual features' model file for the depth view read through f_θ
        /// (default: the shipped one, embedded in the binary; "none": no such view).
        #[arg(long)]
        visual_model: Option<String>,
    },
    /// Solve one planning problem (JSON file, format: docs/planning-problem.md) and print the plan.
    Plan {
        /// The problem file.
        #[arg(long)]
        problem: PathBuf,
        /// Planning time, s (overrides the file's time_limit_s).
        #[arg(long)]
        time_limit: Option<f64>,
        /// Also write the solution as JSON here.
        #[arg(long)]
        json: Option<PathBuf>,
    },
    /// Export a scenario's start, goal and true debris motion as a planning problem file.
    PlanProblem {
        #[command(flatten)]
        common: Common,
        /// The problem file to write.
        #[arg(long)]
        out: PathBuf,
    },
    /// Record every service of a live run into an MCAP file (JSON messages with JSON schemas:
    /// Foxglove shows them); `dkrrt launch --record FILE` starts it for you.
    Recorder {
        /// Run id to record.
        #[arg(long)]
        run: String,
        /// The MCAP file to create (never overwritten).
        #[arg(long)]
        out: PathBuf,
        /// Write the recorder's statistics as JSON here at exit.
        #[arg(long)]
        stats: Option<PathBuf>,
    },
    /// Republish a recording's arm-side messages (robot state, torque commands, debris
    /// observations, goals) on a run id, so `dkrrt predictor` and `dkrrt planner` re-run on it.
    Replay {
        /// The MCAP file (`dkrrt launch --record`); an interrupted one replays up to its end.
        file: PathBuf,
        /// Run id to publish on (start the predictor / planner on it).
        #[arg(long)]
        run: String,
        /// Pace: 1 = as recorded, 4 = four times faster, 0 = as fast as possible.
        #[arg(long, default_value_t = 1.0)]
        speed: f64,
    },
    /// The fault matrix: kill -9 / SIGSTOP of each process, NaN and out-of-range messages on
    /// each service, a rogue trajectory source, a full disk for the report; one line per case
    /// (expected, observed, pass/fail); fails if any case fails (~4 min).
    Faults {
        /// Run only the cases whose name contains this text (e.g. "kill", "tracker").
        #[arg(long)]
        only: Option<String>,
        /// Also write the table as JSON here.
        #[arg(long)]
        json: Option<PathBuf>,
    },
    /// Run the same cores in process, in lockstep (deterministic, no IPC); print the result as JSON.
    Eval {
        #[command(flatten)]
        common: Common,
    },
    /// Threat episodes in lockstep, per scene and method: completion (95 % intervals),
    /// collisions, execution and path errors, planning time; dk-rrt paired with every method.
    Study {
        /// Comma-separated scenes (default: all four).
        #[arg(long, value_delimiter = ',')]
        scenes: Option<Vec<String>>,
        /// Study size: episodes per scene small = 2 (a smoke run; the tests run it), medium = 40, full = 100.
        #[arg(long, default_value = "medium", value_parser = ["small", "medium", "full"])]
        size: String,
        /// Episodes per scene (overrides --size).
        #[arg(long)]
        episodes: Option<u64>,
        /// Comma-separated methods (default: all six): straight, rrt-static, cv-rrt, edmd-rrt,
        /// dk-rrt, oracle-rrt; and dk-rrt-depth (dk-rrt seeing through the depth camera) and
        /// dk-rrt-visual (the same with the learned visual features f_θ).
        #[arg(
            long,
            value_delimiter = ',',
            default_value = "straight,rrt-static,cv-rrt,edmd-rrt,dk-rrt,oracle-rrt"
        )]
        methods: Vec<String>,
        /// Master seed of the episodes.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Write {rows, summary} as JSON here (rows also stream to FILE.rows.jsonl as JSON lines).
        #[arg(long)]
        json: Option<PathBuf>,
        /// Write study.json (rows + summary), study.md (tables, split, machine, command, git
        /// revision) and rows.jsonl (streamed as episodes finish) into this directory.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Worker threads (default: the available cores).
        #[arg(long)]
        threads: Option<usize>,
        /// The episodes' goals: `joint` (the goal configuration) or `pose` (its end-effector
        /// pose, solved by IK by the sources; reached within 1 cm and 0.02 rad).
        #[arg(long, default_value = "joint", value_parser = ["joint", "pose"])]
        goal: String,
        /// Train the deep attitude network first (as `dkrrt train`, ~30 s) and plan dk-rrt on
        /// it, reporting its training time beside the other methods' fitting times (default:
        /// the shipped network, trained offline).
        #[arg(long)]
        train_deep: bool,
        /// Build every episode on this scenario file instead of the embedded default: its
        /// camera, limits, predictor and planner settings (its `[episode]` is replaced by each
        /// generated one, its debris scene by the episode's).
        #[arg(long)]
        scenario: Option<PathBuf>,
    },
}

/// `--seconds` of `dkrrt record`, checked before the scenario is built.
fn seconds_arg(s: &str) -> Result<f64, String> {
    let v: f64 = s.parse().map_err(|e| format!("{s:?}: {e}"))?;
    dkrrt_planner::record_process::check_seconds(v)
}

fn scenario(c: &Common) -> Result<Scenario, String> {
    let mut sc = Scenario::load(&c.scenario).map_err(|e| e.to_string())?;
    if let Some(m) = &c.mode {
        sc.run.mode = m.parse::<Mode>()?;
    }
    if let Some(d) = c.duration {
        sc.run.duration_s = d;
    }
    // Validate against the arm now, so a bad scenario fails before anything starts.
    sc.load_arm().map_err(|e| e.to_string())?;
    // A threat episode: every process regenerates the same start, goal and debris.
    let duration = sc.run.duration_s;
    let episode = dkrrt_episodes::resolve(&mut sc).map_err(|e| format!("scenario {}: {e}", c.scenario))?;
    if episode.is_some() && c.duration.is_some() {
        sc.run.duration_s = duration;
    }
    Ok(sc)
}

/// `--goal`: exactly six finite joint positions.
fn joint_goal(g: Option<Vec<f64>>) -> Result<Option<[f64; 6]>, String> {
    let Some(g) = g else { return Ok(None) };
    if g.len() != 6 {
        return Err(format!("--goal: {} numbers given; give the six joint positions (rad), e.g. --goal 0.35,-0.2,0.7,0.3,0.2,0.4", g.len()));
    }
    if let Some(i) = g.iter().position(|x| !x.is_finite()) {
        return Err(format!("--goal[{i}] = {}: must be finite", g[i]));
    }
    Ok(Some(std::array::from_fn(|i| g[i])))
}

fn main() -> ExitCode {
    // A closed pipe (`dkrrt eval | head -1`) ends the process quietly, as for any Unix tool,
    // instead of a panic in `println!`.
    // SAFETY: restoring the default disposition of SIGPIPE before any thread starts.
    unsafe { libc::signal(libc::SIGPIPE, libc::SIG_DFL) };
    let cli = Cli::parse();
    let res: Result<bool, String> = (|| match cli.cmd {
        Cmd::Launch { common, report, run, figures, record, driver } => {
            let sc = scenario(&common)?;
            // The predictor's model files, read before any process starts.
            dkrrt_planner::predict::check_model_files(&sc)?;
            // What loading the arm's URDF ignored or assumed, said once.
            for n in sc.load_arm().map_err(|e| e.to_string())?.load_notes() {
                println!("dkrrt: arm: {}", dkrrt_io::printable(n));
            }
            // Where the report goes is checked before anything starts.
            dkrrt::launch::check_writable(&report)
                .map_err(|e| format!("--report {}: {e}", report.display()))?;
            if let Some(r) = &record {
                if r.exists() {
                    return Err(format!(
                        "--record {}: exists (a recording is never overwritten)",
                        r.display()
                    ));
                }
                dkrrt::launch::check_writable(r).map_err(|e| format!("--record {}: {e}", r.display()))?;
            }
            let (r, ok) = launch(LaunchOptions {
                scenario: sc,
                report: report.clone(),
                run,
                quiet: false,
                figures,
                record,
                driver: if driver == "udp" { Driver::Udp } else { Driver::Sim },
            })?;
            println!("{}", summary(&r));
            println!("report: {}", report.display());
            Ok(ok)
        }
        Cmd::Planner { p, goal, restart } => {
            let sc = scenario(&p.common)?;
            let goal = joint_goal(goal)?;
            let first_id = u64::from(restart) * 1_000_000 + 1;
            dkrrt_planner::planner_process::run(
                &p.run,
                &sc,
                goal,
                first_id,
                p.stats.as_deref(),
                p.trace.as_deref(),
            )
            .map(|_| true)
        }
        Cmd::Sim { p, gate_trajectory, gate_predictor, gate_planner } => {
            let sc = scenario(&p.common)?;
            dkrrt_sim::process::run(
                &p.run,
                &sc,
                dkrrt_sim::process::Gate {
                    trajectory: gate_trajectory,
                    predictor: gate_predictor,
                    planner: gate_planner,
                },
                p.stats.as_deref(),
                p.trace.as_deref(),
            )
            .map(|_| true)
        }
        Cmd::UdpDriver { p, listen, arm } => {
            let sc = scenario(&p.common)?;
            let ep = dkrrt_udp_driver::process::Endpoints { listen, arm };
            dkrrt_udp_driver::process::run(&p.run, &sc, ep, p.stats.as_deref()).map(|_| true)
        }
        Cmd::Latency { common, load, out } => {
            let sc = scenario(&common)?;
            let load = dkrrt::latency::Load::parse(&load)?;
            // The suite's verdict is in its printout and JSON; it ran if it got this far.
            dkrrt::latency::run(&sc, common.duration.unwrap_or(10.0), load, &out).map(|_| true)
        }
        Cmd::LatencyEcho { common, ping_run, pong_run, seconds, stats } => {
            let sc = scenario(&common)?;
            dkrrt::latency::echo(&sc, &ping_run, &pong_run, seconds, &stats).map(|_| true)
        }
        Cmd::ArmEmulator { common, listen, driver, stats } => {
            let sc = scenario(&common)?;
            dkrrt_emulator::process::run(&sc, listen, driver, stats.as_deref()).map(|_| true)
        }
        Cmd::Tracker(p) => {
            let sc = scenario(&p.common)?;
            dkrrt_tracker::process::run(&p.run, &sc, p.stats.as_deref(), p.trace.as_deref()).map(|_| true)
        }
        Cmd::Goto { p, goal } => {
            let sc = scenario(&p.common)?;
            let goal = joint_goal(goal)?;
            dkrrt_planner::process::run(&p.run, &sc, goal, p.stats.as_deref()).map(|_| true)
        }
        Cmd::Predictor(p) => {
            let sc = scenario(&p.common)?;
            dkrrt_planner::predictor_process::run(&p.run, &sc, p.stats.as_deref()).map(|_| true)
        }
        Cmd::Train { out, visual: true, quick, epochs, .. } => {
            dkrrt::visual_train::train_visual(&out.unwrap_or_else(|| "visual.dkv".into()), quick, epochs)
                .map(|_| true)
        }
        Cmd::Train { out, quick, epochs, json, observations, scenario, .. } => {
            let out = out.unwrap_or_else(|| "deep-attitude.dkm".into());
            let recorded = match observations {
                Some(files) => Some((files, Scenario::load(&scenario).map_err(|e| e.to_string())?)),
                None => None,
            };
            dkrrt::train::train(&out, quick, epochs, json.as_deref(), recorded).map(|_| true)
        }
        Cmd::Goal { common, run, q, pose, wait } => {
            use dkrrt_planner::goal_cli::{goal_message, send, GoalRequest};
            if !(wait.is_finite() && wait >= 0.0) {
                return Err(format!("--wait {wait}: must be a finite number of seconds >= 0"));
            }
            let req = match (q, pose) {
                (Some(q), None) if q.len() == 6 => GoalRequest::Joint(std::array::from_fn(|i| q[i])),
                (None, Some(p)) if p.len() == 7 => {
                    GoalRequest::Pose([p[0], p[1], p[2]], [p[3], p[4], p[5], p[6]])
                }
                (Some(q), None) => {
                    return Err(format!("--q: {} numbers given; give the 6 joint positions (rad)", q.len()))
                }
                (None, Some(p)) => {
                    return Err(format!("--pose: {} numbers given; give 7: x,y,z (m), qw,qx,qy,qz", p.len()))
                }
                _ => return Err("goal: give --q (6 joint positions) or --pose (x,y,z,qw,qx,qy,qz)".into()),
            };
            let sc = scenario(&common)?;
            let g = goal_message(&sc, req, 1).map_err(|e| format!("goal: {e}"))?;
            let n = send(&run, g, wait).map_err(|e| format!("goal: {e}"))?;
            eprintln!("goal: sent to {n} subscriber(s) of run {run:?}");
            Ok(true)
        }
        Cmd::Record { common, run, out, seconds } => {
            let sc = scenario(&common)?;
            let r = dkrrt_planner::record_process::run(&run, &sc, &out, seconds)?;
            eprintln!(
                "record: {} items written to {} ({} frames, {} lost, {} rejected, {} invalid items)",
                r.items_written,
                out.display(),
                r.frames,
                r.frames_lost,
                r.frames_rejected,
                r.items_invalid
            );
            Ok(true)
        }
        Cmd::PredictEval { json, size, model, scenes, methods, seed, visual_model } => {
            dkrrt::train::predict_eval(
                &size,
                model.as_deref(),
                scenes,
                methods,
                seed,
                json.as_deref(),
                visual_model.as_deref(),
            )
            .map(|_| true)
        }
        Cmd::Study {
            scenes,
            size,
            episodes,
            methods,
            seed,
            json,
            out,
            threads,
            goal,
            train_deep,
            scenario,
        } => {
            let scenes =
                scenes.unwrap_or_else(|| dkrrt_debris::SCENE_NAMES.iter().map(|s| s.to_string()).collect());
            // A scene file, named relative to here: made absolute (each episode's scenario
            // would resolve it against its own directory).
            let scenes: Vec<String> = scenes
                .into_iter()
                .map(|s| {
                    if dkrrt_config::is_scene_path(&s) {
                        std::fs::canonicalize(&s).map(|p| p.display().to_string()).unwrap_or(s)
                    } else {
                        s
                    }
                })
                .collect();
            let episodes = episodes.unwrap_or(match size.as_str() {
                "small" => 2,
                "full" => 100,
                _ => 40,
            });
            // Every output path is checked before the study runs (nothing is learnt late).
            if let Some(p) = &json {
                dkrrt::launch::check_writable(p).map_err(|e| format!("--json {}: {e}", p.display()))?;
            }
            if let Some(d) = &out {
                std::fs::create_dir_all(d).map_err(|e| format!("--out {}: {e}", d.display()))?;
            }
            let threads =
                threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
            let opts = dkrrt::study::StudyOptions {
                scenes: scenes.clone(),
                episodes,
                methods: methods.clone(),
                seed,
                threads,
                pose_goals: goal == "pose",
                train_deep,
                scenario: scenario.map(|p| p.display().to_string()),
            };
            // A bad base scenario is reported before anything runs; the report states the split
            // of this one.
            let base = dkrrt::study::base_scenario_of(&opts)?;
            let rows_path = match (&out, &json) {
                (Some(d), _) => Some(d.join("rows.jsonl")),
                (None, Some(p)) => Some(p.with_extension("rows.jsonl")),
                _ => None,
            };
            let t0 = std::time::Instant::now();
            let (rows, fits) = dkrrt::study::run(&opts, rows_path.as_deref(), true)?;
            let wall_s = t0.elapsed().as_secs_f64();
            let summary = dkrrt::study_report::summarize(
                &rows,
                &scenes,
                &methods,
                dkrrt::study::fit_costs(&fits),
                seed,
            );
            println!("{}", dkrrt::study::table(&rows, &scenes, &methods));
            println!(
                "{} episodes x methods in {wall_s:.1} s wall ({threads} threads, seed {seed})",
                rows.len()
            );
            let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
            if threads > 1 {
                println!(
                    "note: the lockstep speed is each episode's plant time over its wall time, here with {threads} \
                     episodes at once on {cores} cores{}; --threads 1 gives each episode the machine",
                    if threads >= cores { " (no core left to step their debris side ahead)" } else { "" }
                );
            }
            let stale: u64 = rows.iter().map(|r| r.stale_forecast_reads).sum();
            if stale > 0 {
                println!(
                    "note: {stale} planner cycles read an older forecast than the process set would have \
                     (the predictor's input stalled; stale_forecast_reads in the rows)"
                );
            }
            let refused: Vec<&dkrrt::study::Row> = rows.iter().filter(|r| r.forecasts_refused > 0).collect();
            if let Some(r) = refused.first() {
                println!(
                    "warning: in {} episodes the planner refused forecasts ({} in all; {} {} {}: {}): \
                     in the process set each fails the run's verdict (forecasts_refused in the rows)",
                    refused.len(),
                    refused.iter().map(|r| r.forecasts_refused).sum::<u64>(),
                    r.scene,
                    r.episode,
                    r.method,
                    r.forecast_error.as_deref().unwrap_or("stamped ahead of the plant clock")
                );
            }
            let info = dkrrt::study_report::RunInfo::now(&opts, &size, &goal, wall_s);
            let doc = serde_json::json!({
                "seed": seed, "episodes": episodes, "scenes": scenes, "methods": methods, "goal": goal,
                "scenario": opts.scenario.as_deref().unwrap_or("<embedded default>"),
                "run": info, "split": dkrrt::study_report::split_text(&opts, &base), "summary": summary, "rows": rows,
            });
            let text = serde_json::to_string_pretty(&doc).map_err(|e| e.to_string())?;
            if let Some(p) = &json {
                std::fs::write(p, &text).map_err(|e| format!("--json {}: {e}", p.display()))?;
                println!("rows: {}", p.display());
            }
            if let Some(d) = &out {
                let w = |name: &str, body: &str| {
                    std::fs::write(d.join(name), body)
                        .map_err(|e| format!("--out {}: {e}", d.join(name).display()))
                };
                w("study.json", &text)?;
                // The figures: Fig. 3 from the summary; Fig. 2, Fig. 4 and the clearance plot
                // from a traced re-run of the dk-rrt episode that came closest to the debris.
                let figs = d.join("figures");
                std::fs::create_dir_all(&figs).map_err(|e| format!("--out {}: {e}", figs.display()))?;
                let pick = rows
                    .iter()
                    .filter(|r| r.method == "dk-rrt" && r.completed)
                    .min_by(|a, b| {
                        a.min_distance_m
                            .unwrap_or(f64::INFINITY)
                            .total_cmp(&b.min_distance_m.unwrap_or(f64::INFINITY))
                    })
                    .or_else(|| rows.iter().find(|r| r.error.is_none()));
                let trace = match pick {
                    Some(r) => {
                        Some(dkrrt::study::trace_episode(&opts, &fits, &r.scene, r.episode, &r.method)?)
                    }
                    None => None,
                };
                let files = dkrrt::figures::study_figures(&figs, &summary, trace.as_ref())?;
                let md =
                    dkrrt::study_report::markdown(&summary, &opts, &base, &info, &files, d, trace.as_ref());
                w("study.md", &md)?;
                println!("study: {} ({} figure files)", d.display(), files.len());
            }
            Ok(rows.iter().all(|r| r.error.is_none()))
        }
        Cmd::Plan { problem, time_limit, json } => {
            let sol = dkrrt::plan_cli::plan(&problem, time_limit)?;
            let text = serde_json::to_string_pretty(&sol).map_err(|e| e.to_string())?;
            if let Some(p) = &json {
                std::fs::write(p, &text).map_err(|e| format!("--json {}: {e}", p.display()))?;
            }
            println!(
                "solved {}  first solution {}  plan time {:.3} s  iterations {}  duration {:.2} s  path {:.3} rad  min clearance {}",
                sol.solved,
                sol.first_solution_s.map_or("-".into(), |t| format!("{:.4} s", t)),
                sol.plan_time_s,
                sol.iterations,
                sol.duration_s,
                sol.path_length_rad,
                match (sol.min_clearance_m, sol.trajectory.is_empty()) {
                    (Some(m), _) => format!("{m:.3} m"),
                    (None, false) => format!("- (nothing within {} m)", dkrrt_rrt::problem::MEASURED_UP_TO_M),
                    (None, true) => "-".into(),
                },
            );
            if let Some(why) = &sol.why {
                eprintln!("dkrrt plan: not solved: {why}");
            }
            if json.is_none() {
                println!("{text}");
            }
            Ok(sol.solved)
        }
        Cmd::PlanProblem { common, out } => {
            let sc = scenario(&common)?;
            let p = dkrrt::plan_cli::export(&sc)?;
            let text = serde_json::to_string(&p).map_err(|e| e.to_string())?;
            std::fs::write(&out, text).map_err(|e| format!("--out {}: {e}", out.display()))?;
            println!(
                "problem: {} ({} obstacles, {:.1} s of motion)",
                out.display(),
                p.obstacles.len(),
                sc.run.duration_s
            );
            Ok(true)
        }
        Cmd::Recorder { run, out, stats } => {
            let r = dkrrt::mcap_io::record(&run, &out)?;
            dkrrt_rt::write_stats("recorder", stats.as_deref(), &r)?;
            eprintln!("recorder: {} messages to {}", r.messages, out.display());
            Ok(true)
        }
        Cmd::Replay { file, run, speed } => {
            let r = dkrrt::mcap_io::replay(&file, &run, speed)?;
            println!("{}", serde_json::to_string_pretty(&r).map_err(|e| e.to_string())?);
            Ok(true)
        }
        Cmd::Faults { only, json } => {
            if let Some(p) = &json {
                dkrrt::launch::check_writable(p).map_err(|e| format!("--json {}: {e}", p.display()))?;
            }
            let rows = dkrrt::faults::run(only.as_deref())?;
            if let Some(p) = &json {
                let text = serde_json::to_string_pretty(&rows).map_err(|e| e.to_string())?;
                std::fs::write(p, text).map_err(|e| format!("--json {}: {e}", p.display()))?;
            }
            Ok(!rows.is_empty() && rows.iter().all(|r| r.pass))
        }
        Cmd::Eval { common } => {
            if common.mode.as_deref() == Some("realtime") {
                return Err("eval --mode realtime: eval runs in lockstep, in process (`dkrrt launch` runs in real time)".into());
            }
            let sc = scenario(&common)?;
            let r = dkrrt::lockstep::run(&sc)?;
            println!("{}", serde_json::to_string_pretty(&r).map_err(|e| e.to_string())?);
            for c in r.checks.iter().filter(|c| !c.ok) {
                eprintln!("dkrrt eval: check {} failed: {}", c.name, c.detail);
            }
            // Exit status 1 when the run did not do what was asked (as `dkrrt launch`).
            Ok(r.ok)
        }
    })();
    match res {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::from(1),
        Err(e) => {
            eprintln!("dkrrt: error: {e}");
            ExitCode::from(2)
        }
    }
}

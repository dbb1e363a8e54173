//! The `dkrrt` command line.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};
use dkrrt::launch::{launch, summary, LaunchOptions};
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
}

#[derive(Subcommand)]
enum Cmd {
    /// Start sim, tracker and the trajectory source as separate processes, supervise them, report.
    Launch {
        #[command(flatten)]
        common: Common,
        /// Where to write the JSON report.
        #[arg(long, default_value = "dkrrt-report.json")]
        report: PathBuf,
        /// Run id (default: generated, unique per launch).
        #[arg(long)]
        run: Option<String>,
    },
    /// The plant simulator process: integrates the arm under commanded torques, publishes state at 1 kHz.
    Sim {
        #[command(flatten)]
        p: ProcArgs,
        /// Lockstep only: hold at tick 0 until a trajectory has been published.
        #[arg(long)]
        gate_trajectory: bool,
    },
    /// The 1 kHz computed-torque tracker process.
    Tracker(ProcArgs),
    /// The trajectory source: plans a jerk-limited trajectory to a joint goal and publishes it.
    Goto {
        #[command(flatten)]
        p: ProcArgs,
        /// Joint goal in rad, comma separated (default: the scenario's goal).
        #[arg(long, value_delimiter = ',', num_args = 6)]
        goal: Option<Vec<f64>>,
    },
    /// Run the same cores in process, in lockstep (deterministic, no IPC); print the result as JSON.
    Eval {
        #[command(flatten)]
        common: Common,
    },
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
    Ok(sc)
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let res: Result<bool, String> = (|| match cli.cmd {
        Cmd::Launch { common, report, run } => {
            let sc = scenario(&common)?;
            let (r, ok) = launch(LaunchOptions { scenario: sc, report: report.clone(), run, quiet: false })?;
            println!("{}", summary(&r));
            println!("report: {}", report.display());
            Ok(ok)
        }
        Cmd::Sim { p, gate_trajectory } => {
            let sc = scenario(&p.common)?;
            dkrrt_sim::process::run(&p.run, &sc, gate_trajectory, p.stats.as_deref()).map(|_| true)
        }
        Cmd::Tracker(p) => {
            let sc = scenario(&p.common)?;
            dkrrt_tracker::process::run(&p.run, &sc, p.stats.as_deref()).map(|_| true)
        }
        Cmd::Goto { p, goal } => {
            let sc = scenario(&p.common)?;
            let goal = goal.map(|g| {
                let mut a = [0.0; 6];
                a.copy_from_slice(&g);
                a
            });
            dkrrt_planner::process::run(&p.run, &sc, goal, p.stats.as_deref()).map(|_| true)
        }
        Cmd::Eval { common } => {
            let sc = scenario(&common)?;
            let r = dkrrt::lockstep::run(&sc)?;
            println!("{}", serde_json::to_string_pretty(&r).map_err(|e| e.to_string())?);
            Ok(true)
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

//! The scenario's `[planner]` table as the DK-RRT replanning core: one mapping, used by the
//! `dkrrt planner` process and by the in-process lockstep.

use dkrrt_config::Scenario;
use dkrrt_rrt::{PlannerConfig, ReplanConfig, Replanner};

/// The planner and replanning settings of a scenario.
pub fn configs(sc: &Scenario) -> (PlannerConfig, ReplanConfig) {
    let p = &sc.planner;
    let pc = PlannerConfig {
        delta_m: p.delta_m,
        lookahead_s: p.lookahead_s,
        seed: p.seed,
        ..PlannerConfig::default()
    };
    let rc = ReplanConfig {
        cycle_s: 1.0 / p.rate_hz,
        deadline_s: p.deadline_ms * 1e-3,
        commit_s: p.commit_ms * 1e-3,
        margin_m: p.margin_m,
        iterations: p.iterations,
        enforce_deadline: sc.run.mode == dkrrt_config::Mode::Realtime,
        ..ReplanConfig::default()
    };
    (pc, rc)
}

/// The replanning core of a scenario (the same for the process and the lockstep).
pub fn replanner(sc: &Scenario, model: dkrrt_model::ArmModel) -> Replanner {
    let (pc, rc) = configs(sc);
    let limits = dkrrt_otg::Limits { v_max: sc.motion.v_max, a_max: sc.motion.a_max, j_max: sc.motion.j_max };
    let lim = dkrrt_config::arm::contract_limits(&model);
    let mut core = Replanner::new(model, limits, pc, rc, sc.has_debris());
    core.set_contract(lim);
    core
}

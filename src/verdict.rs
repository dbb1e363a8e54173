//! The verdict of a process-set run: a run is `ok` only when it did what was asked. A pure
//! function of the scenario's `[checks]` and the processes' statistics, so it is tested
//! without launching anything.

use serde::Serialize;
use serde_json::Value;

use dkrrt_config::Scenario;

/// One check of the verdict.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Check {
    pub name: &'static str,
    pub ok: bool,
    /// What was measured (and the bound), in words.
    pub detail: String,
}

/// What the launcher knows about how the processes ended.
#[derive(Debug, Clone, Default)]
pub struct Ending {
    /// The first failure the supervisor saw (a process died or hung, a signal, the time limit).
    pub failure: Option<String>,
    /// Processes that did not exit with status 0, with how they ended.
    pub unclean: Vec<String>,
    /// Nodes on the run's bus the launcher did not start (name and pid).
    pub rogue: Vec<String>,
}

fn num(v: &Value, p: &str) -> Option<f64> {
    v.pointer(p).and_then(Value::as_f64)
}

fn count(v: &Value, p: &str) -> u64 {
    v.pointer(p).and_then(Value::as_u64).unwrap_or(0)
}

/// The checks of a run from the statistics of sim, tracker, goto, planner and predictor
/// (`Value::Null` for a process that did not run or left none).
pub fn checks(
    sc: &Scenario,
    end: &Ending,
    sim: &Value,
    tr: &Value,
    goto: &Value,
    plan: &Value,
    pred: &Value,
) -> Vec<Check> {
    let k = &sc.checks;
    let mut out = Vec::new();
    let mut push = |name, ok, detail: String| out.push(Check { name, ok, detail });

    push(
        "supervision",
        end.failure.is_none(),
        end.failure.clone().unwrap_or_else(|| "every process ran to the end of the run".into()),
    );
    push(
        "clean_exits",
        end.unclean.is_empty(),
        if end.unclean.is_empty() {
            "every process exited with status 0".into()
        } else {
            end.unclean.join("; ")
        },
    );

    let foreign = count(tr, "/foreign_trajectories");
    let foreign_states = count(tr, "/foreign_states");
    push(
        "no_rogue_publishers",
        end.rogue.is_empty() && foreign == 0 && foreign_states == 0,
        format!(
            "{} foreign node(s){}; {foreign} trajectories and {foreign_states} robot states from a publisher the run did not start (ignored)",
            end.rogue.len(),
            if end.rogue.is_empty() { String::new() } else { format!(": {}", end.rogue.join(", ")) }
        ),
    );

    // The goal: the arm ends within the tolerance of the goal of the trajectory it followed
    // (and, with the planner, the planner saw it reached).
    let fe = num(tr, "/final_error_rad");
    let goal_ok = fe.is_some_and(|e| e <= k.goal_tolerance_rad)
        && (!sc.replans() || plan.get("goal_reached_s").is_some_and(|g| !g.is_null()));
    push(
        "goal_reached",
        goal_ok,
        match fe {
            Some(e) => format!("final joint error {e:.3e} rad (tolerance {} rad)", k.goal_tolerance_rad),
            None if tr.is_null() => "no tracker statistics".into(),
            None => "no trajectory was followed".into(),
        },
    );

    if sc.has_debris() {
        let c = sim.pointer("/debris/first_contact").filter(|c| !c.is_null());
        push(
            "no_collision",
            c.is_none() && !sim.is_null(),
            match c {
                Some(c) => format!("link {} hit debris {} at t = {} s", c["link"], c["debris_id"], c["t_s"]),
                None => format!(
                    "min distance {} m",
                    sim.pointer("/debris/min_distance_m").unwrap_or(&Value::Null)
                ),
            },
        );
    }

    // Joint limits, on the plant's true state.
    let ratio = num(sim, "/plant/max_velocity_ratio");
    let hits = count(sim, "/plant/limit_hits");
    let nonfinite = count(sim, "/plant/non_finite_steps");
    push(
        "joint_limits",
        ratio.is_some_and(|r| r <= 1.0) && hits == 0 && nonfinite == 0,
        match ratio {
            Some(r) => format!(
                "peak joint speed {:.0} % of its limit, {} ticks over it, {hits} hard-stop hits, {nonfinite} non-finite steps",
                r * 100.0,
                count(sim, "/plant/velocity_limit_ticks")
            ),
            None => "no plant statistics".into(),
        },
    );

    // Messages refused by the contract, by every reader.
    let rejected = [
        ("tracker states", count(tr, "/rejected/state")),
        ("tracker trajectories", count(tr, "/rejected/trajectory")),
        ("sim commands", count(sim, "/commands_rejected")),
        ("goto states", count(goto, "/states_rejected")),
        ("planner", count(plan, "/rejected")),
        ("predictor frames", count(pred, "/observations/frames_rejected")),
        ("predictor items", count(pred, "/observations/items_invalid")),
    ];
    let total: u64 = rejected.iter().map(|r| r.1).sum();
    let list: Vec<String> = rejected.iter().filter(|r| r.1 > 0).map(|r| format!("{} {}", r.1, r.0)).collect();
    // Why, where the reader says (the newest refusal per input).
    let why: Vec<&str> = plan
        .get("rejections")
        .and_then(Value::as_array)
        .map(|v| v.iter().filter_map(Value::as_str).collect())
        .unwrap_or_default();
    push(
        "rejected_messages",
        total <= k.max_rejected_messages,
        format!(
            "{total} rejected{} (at most {}){}",
            if list.is_empty() { String::new() } else { format!(": {}", list.join(", ")) },
            k.max_rejected_messages,
            if why.is_empty() { String::new() } else { format!("; last: {}", why.join("; ")) }
        ),
    );

    let holds = count(tr, "/safe_hold_entries");
    let brakes = count(sim, "/plant/brake_engagements");
    // The controlled stop's brakes forced by the driver (the sim's are plant brake
    // engagements too; a network driver's are the arm's own, which the emulator's plant
    // figures do not count): the controller did not bring the arm to rest.
    let forced = sim.pointer("/stop/brakes_forced").and_then(Value::as_bool) == Some(true);
    push(
        "safe_holds",
        holds <= k.max_safe_holds && brakes == 0 && !forced,
        format!(
            "{holds} safe holds (at most {}), {brakes} plant brake engagements (none allowed){}",
            k.max_safe_holds,
            if forced { ", the stop's brakes forced: not at rest 5 s after it began" } else { "" }
        ),
    );
    out
}

/// The names of the failed checks.
pub fn failed(checks: &[Check]) -> Vec<&'static str> {
    checks.iter().filter(|c| !c.ok).map(|c| c.name).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn healthy() -> (Value, Value, Value) {
        let sim = json!({
            "commands_rejected": 0,
            "plant": {"max_velocity_ratio": 0.8, "limit_hits": 0, "non_finite_steps": 0, "velocity_limit_ticks": 0, "brake_engagements": 0},
            "debris": {"first_contact": null, "min_distance_m": 0.3},
        });
        let tr = json!({"final_error_rad": 1e-6, "rejected": {"state": 0, "trajectory": 0}, "safe_hold_entries": 0, "foreign_trajectories": 0, "foreign_states": 0});
        let plan = json!({"goal_reached_s": 9.1, "rejected": 0});
        (sim, tr, plan)
    }

    fn verdict(sc: &Scenario, end: &Ending, sim: &Value, tr: &Value, plan: &Value) -> Vec<&'static str> {
        failed(&checks(sc, end, sim, tr, &Value::Null, plan, &Value::Null))
    }

    #[test]
    fn a_healthy_run_passes_every_check() {
        let sc = Scenario::default_scenario();
        let (sim, tr, plan) = healthy();
        assert!(verdict(&sc, &Ending::default(), &sim, &tr, &plan).is_empty());
    }

    #[test]
    fn each_failure_fails_its_check() {
        let sc = Scenario::default_scenario();
        let end = Ending::default();
        let (sim, tr, plan) = healthy();
        let with = |v: &Value, p: &str, x: Value| {
            let mut v = v.clone();
            *v.pointer_mut(p).unwrap() = x;
            v
        };
        // An unstable arm: speed over the limit, states rejected (the kp = 4e5 run).
        let s = with(&sim, "/plant/max_velocity_ratio", json!(60.0));
        assert_eq!(verdict(&sc, &end, &s, &tr, &plan), ["joint_limits"]);
        let t = with(&tr, "/rejected/state", json!(5584));
        assert_eq!(verdict(&sc, &end, &sim, &t, &plan), ["rejected_messages"]);
        // A goal missed by 1.3 rad; no trajectory followed at all.
        assert_eq!(
            verdict(&sc, &end, &sim, &with(&tr, "/final_error_rad", json!(1.3)), &plan),
            ["goal_reached"]
        );
        assert_eq!(
            verdict(&sc, &end, &sim, &with(&tr, "/final_error_rad", Value::Null), &plan),
            ["goal_reached"]
        );
        assert_eq!(
            verdict(&sc, &end, &sim, &tr, &with(&plan, "/goal_reached_s", Value::Null)),
            ["goal_reached"]
        );
        // The stop's brakes forced by a network driver (no plant brake counted).
        let s = with(&sim, "/plant/brake_engagements", json!(0));
        let mut s2 = s.clone();
        s2["stop"] = json!({"cause": "duration", "brakes_forced": true, "at_rest": true});
        assert_eq!(verdict(&sc, &end, &s2, &tr, &plan), ["safe_holds"]);
        s2["stop"]["brakes_forced"] = json!(false);
        assert!(verdict(&sc, &end, &s2, &tr, &plan).is_empty());
        // A collision; hard-stop hits; a NaN plant step.
        let s = with(&sim, "/debris/first_contact", json!({"link": 2, "debris_id": 9, "t_s": 0.0}));
        assert_eq!(verdict(&sc, &end, &s, &tr, &plan), ["no_collision"]);
        assert_eq!(
            verdict(&sc, &end, &with(&sim, "/plant/limit_hits", json!(3)), &tr, &plan),
            ["joint_limits"]
        );
        assert_eq!(
            verdict(&sc, &end, &with(&sim, "/plant/non_finite_steps", json!(1)), &tr, &plan),
            ["joint_limits"]
        );
        // Safe holds over the bound; any plant brake engagement.
        let t = with(&tr, "/safe_hold_entries", json!(sc.checks.max_safe_holds + 1));
        assert_eq!(verdict(&sc, &end, &sim, &t, &plan), ["safe_holds"]);
        let t = with(&tr, "/safe_hold_entries", json!(sc.checks.max_safe_holds));
        assert!(verdict(&sc, &end, &sim, &t, &plan).is_empty());
        assert_eq!(
            verdict(&sc, &end, &with(&sim, "/plant/brake_engagements", json!(1)), &tr, &plan),
            ["safe_holds"]
        );
        // Supervision and exits.
        let e = Ending {
            failure: Some("process planner died (signal 9)".into()),
            unclean: vec!["planner: signal 9".into()],
            rogue: vec![],
        };
        assert_eq!(verdict(&sc, &e, &sim, &tr, &plan), ["supervision", "clean_exits"]);
        // A rogue publisher: a foreign node on the bus, or trajectories the tracker ignored.
        let e = Ending { rogue: vec!["goto (pid 77)".into()], ..Ending::default() };
        assert_eq!(verdict(&sc, &e, &sim, &tr, &plan), ["no_rogue_publishers"]);
        let t = with(&tr, "/foreign_trajectories", json!(3));
        assert_eq!(verdict(&sc, &end, &sim, &t, &plan), ["no_rogue_publishers"]);
        let t = with(&tr, "/foreign_states", json!(2));
        assert_eq!(verdict(&sc, &end, &sim, &t, &plan), ["no_rogue_publishers"]);
        // No statistics at all is no success.
        assert_eq!(
            verdict(&sc, &end, &Value::Null, &Value::Null, &Value::Null),
            ["goal_reached", "no_collision", "joint_limits"]
        );
    }
}

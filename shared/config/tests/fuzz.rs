//! Fuzzing the scenario parser and validator (proptest, bounded): the default scenario with
//! one value replaced by anything never panics, and a scenario that passes holds the bounds
//! every process relies on.

use dkrrt_config::{gain_limits, Scenario, DEFAULT_SCENARIO, MAX_DURATION_S};
use proptest::prelude::*;

/// Byte ranges of the values (after `= `) of the default scenario's `key = value` lines.
fn value_spans() -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut off = 0;
    for line in DEFAULT_SCENARIO.split_inclusive('\n') {
        if let Some(eq) = line.find(" = ") {
            if !line.trim_start().starts_with('#') {
                let start = off + eq + 3;
                let body = &line[eq + 3..];
                let end = body.find("  #").or_else(|| body.find(" #")).unwrap_or(body.trim_end().len());
                out.push((start, start + end));
            }
        }
        off += line.len();
    }
    out
}

fn token() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("nan".to_string()),
        Just("inf".to_string()),
        Just("-inf".to_string()),
        Just("1e308".to_string()),
        Just("-1e308".to_string()),
        Just("0".to_string()),
        Just("\"\"".to_string()),
        Just("[]".to_string()),
        Just("true".to_string()),
        any::<f64>().prop_map(|x| format!("{x:?}")),
        any::<i64>().prop_map(|x| x.to_string()),
        prop::collection::vec(any::<f64>(), 0..9)
            .prop_map(|v| format!("{v:?}").replace("NaN", "nan").replace("inf", "inf")),
        "[a-z\\-/.]{0,12}".prop_map(|s| format!("\"{s}\"")),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn any_single_value_is_parsed_or_refused_without_panicking(i in any::<prop::sample::Index>(), t in token()) {
        let spans = value_spans();
        prop_assume!(!spans.is_empty());
        let (a, b) = spans[i.index(spans.len())];
        let text = format!("{}{}{}", &DEFAULT_SCENARIO[..a], t, &DEFAULT_SCENARIO[b..]);
        let Ok(sc) = Scenario::from_toml_str(&text, "fuzz.toml") else { return Ok(()) };
        if sc.load_arm().is_err() {
            return Ok(());
        }
        // Accepted: the bounds hold.
        let (kp, kd) = gain_limits(sc.run.control_hz);
        prop_assert!(sc.tracker.kp.iter().all(|&g| g > 0.0 && g <= kp));
        prop_assert!(sc.tracker.kd.iter().all(|&g| g > 0.0 && g <= kd));
        prop_assert!(sc.run.duration_s > 0.0 && sc.run.duration_s <= MAX_DURATION_S);
        prop_assert!(sc.sim.noise_q_std.is_finite() && sc.sim.noise_q_std <= 0.05);
        prop_assert!(sc.robot.gravity.iter().all(|g| g.is_finite() && g.abs() <= 100.0));
        prop_assert!(f64::from(sc.tracker.stale_ticks) <= 0.1 * sc.run.control_hz + 1.0);
        prop_assert!(sc.motion.v_max.iter().chain(&sc.motion.a_max).chain(&sc.motion.j_max).all(|x| x.is_finite() && *x > 0.0));
    }
}

#[test]
fn the_fuzzer_reaches_every_value() {
    // 60+ `key = value` lines: the property above is exercised over all sections.
    assert!(value_spans().len() > 60, "{}", value_spans().len());
}

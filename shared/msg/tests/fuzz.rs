//! Fuzzing the message validators (proptest, a bounded number of cases): any bytes in any
//! payload type are validated without panicking, and whatever passes holds what the
//! consumers rely on (finite numbers within the contract's limits, counts within capacity).

use dkrrt_msg::bus::check_run_id;
use dkrrt_msg::*;
use proptest::prelude::*;

fn lim() -> ContractLimits {
    ContractLimits::symmetric(3.0, 2.0, 100.0)
}

/// A payload with the given bytes (every payload is plain integers and floats, so every bit
/// pattern is a value).
fn from_bytes<T: Zeroed>(bytes: &[u8]) -> Box<T> {
    let mut m = Box::new(T::zeroed());
    let n = std::mem::size_of::<T>().min(bytes.len());
    // SAFETY: T is repr(C) plain numbers (see `Zeroed`); any bytes are a valid T.
    unsafe { std::ptr::copy_nonoverlapping(bytes.as_ptr(), (&mut *m as *mut T).cast::<u8>(), n) };
    m
}

/// Bytes that are mostly a valid-looking message: zeros with a few random words written in
/// (so the validators' later checks are reached, not only the first field's).
fn sparse(len: usize) -> impl Strategy<Value = Vec<u8>> {
    prop::collection::vec((0..len / 8, any::<u64>(), 0u8..4), 1..12).prop_map(move |words| {
        let mut b = vec![0u8; len];
        for (i, w, kind) in words {
            let v: u64 = match kind {
                0 => w,      // anything (NaN, Inf, huge)
                1 => w % 64, // small integers (counts, enums)
                2 => f64::NAN.to_bits(),
                _ => ((w % 2000) as f64 * 1e-3 - 1.0).to_bits(), // plausible floats
            };
            b[i * 8..i * 8 + 8].copy_from_slice(&v.to_le_bytes());
        }
        b
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn robot_states_that_pass_are_finite_and_within_limits(b in sparse(std::mem::size_of::<RobotState>())) {
        let m = from_bytes::<RobotState>(&b);
        if m.validate(&lim()).is_ok() {
            let l = lim();
            for i in 0..6 {
                prop_assert!(m.q[i].is_finite() && m.qd[i].is_finite() && m.tau[i].is_finite());
                prop_assert!(m.q[i].abs() <= l.q_max[i] + l.q_margin);
                prop_assert!(m.qd[i].abs() <= l.v_max[i] * l.v_factor);
                prop_assert!(m.tau[i].abs() <= l.tau_max[i] * (1.0 + 1e-9));
            }
        }
    }

    #[test]
    fn torque_commands_that_pass_are_finite_with_a_known_mode(b in sparse(std::mem::size_of::<TorqueCommand>())) {
        let m = from_bytes::<TorqueCommand>(&b);
        if m.validate(&lim()).is_ok() {
            prop_assert!(m.tau.iter().chain(&m.q_set).chain(&m.qd_set).all(|t| t.is_finite()));
            prop_assert!(ControllerMode::from_u32(m.mode).is_some());
        }
    }

    #[test]
    fn trajectories_that_pass_sample_finite(b in sparse(std::mem::size_of::<Trajectory>()), t in 0.0f64..100.0) {
        let m = from_bytes::<Trajectory>(&b);
        if m.validate(&lim()).is_ok() {
            let s = m.sample(t.min(m.duration_s));
            prop_assert!(s.p.iter().chain(&s.v).chain(&s.a).all(|x| x.is_finite()));
        }
    }

    #[test]
    fn goals_and_statuses_validate_without_panicking(
        g in sparse(std::mem::size_of::<Goal>()),
        s in sparse(std::mem::size_of::<PlanStatus>()),
        h in sparse(std::mem::size_of::<Heartbeat>()),
        p in sparse(std::mem::size_of::<PredictorProgress>()),
    ) {
        let goal = from_bytes::<Goal>(&g);
        if goal.validate(&lim()).is_ok() && goal.kind == GoalKind::Joint as u32 {
            prop_assert!(goal.q.iter().all(|x| x.is_finite()));
        }
        let _ = from_bytes::<PlanStatus>(&s).validate(&lim());
        let _ = from_bytes::<Heartbeat>(&h).validate(&lim());
        let pr = from_bytes::<PredictorProgress>(&p);
        if pr.validate(&lim()).is_ok() {
            prop_assert!(pr.frames <= pr.frame_seq.saturating_add(1));
        }
    }

    #[test]
    fn debris_frames_that_pass_hold_counts_within_capacity(
        o in sparse(std::mem::size_of::<DebrisObservation>()),
        f in sparse(std::mem::size_of::<DebrisForecast>()),
    ) {
        let obs = from_bytes::<DebrisObservation>(&o);
        if obs.validate(&lim()).is_ok() {
            prop_assert!(obs.count as usize <= MAX_DEBRIS);
        }
        // The frame check alone (the predictor then checks item by item).
        if obs.validate_frame().is_ok() {
            prop_assert!(obs.count as usize <= MAX_DEBRIS);
            for (i, it) in obs.items[..obs.count as usize].iter().enumerate() {
                if it.validate_item(&lim(), i).is_ok() {
                    prop_assert!(it.p.iter().chain(&it.q).all(|x| x.is_finite()));
                }
            }
        }
        let fc = from_bytes::<DebrisForecast>(&f);
        if fc.validate(&lim()).is_ok() {
            prop_assert!(fc.count as usize <= MAX_DEBRIS);
            prop_assert!(fc.steps as usize <= FORECAST_STEPS && fc.dt_s.is_finite());
        }
    }

    #[test]
    fn run_ids_are_accepted_exactly_when_well_formed(s in "[a-zA-Z0-9_\\-. /\u{1b}]{0,80}") {
        let ok = !s.is_empty()
            && s.len() <= dkrrt_msg::bus::MAX_RUN_ID
            && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '-')
            && s.starts_with(|c: char| c.is_ascii_alphanumeric());
        prop_assert_eq!(check_run_id(&s).is_ok(), ok, "{:?}", s);
    }
}

#[test]
fn run_ids_at_the_limits() {
    assert!(check_run_id(&"a".repeat(dkrrt_msg::bus::MAX_RUN_ID)).is_ok());
    let e = check_run_id(&"a".repeat(dkrrt_msg::bus::MAX_RUN_ID + 1)).unwrap_err().to_string();
    assert!(e.contains("64 characters"), "{e}");
    let e = check_run_id("-x").unwrap_err().to_string();
    assert!(e.contains("starting with a letter"), "{e}");
    assert!(check_run_id("").is_err());
    // The longest id works with iceoryx2 (a node and a service on it), and leaves nothing.
    let mut run = format!("t{}-", std::process::id());
    while run.len() < dkrrt_msg::bus::MAX_RUN_ID {
        run.push('a');
    }
    let run = run.as_str();
    {
        let bus = dkrrt_msg::bus::Bus::new(run, "probe").unwrap();
        let _p = bus.publisher::<RobotState>(Source::Sim).unwrap();
    }
    dkrrt_msg::bus::remove_run_leftovers(run);
}

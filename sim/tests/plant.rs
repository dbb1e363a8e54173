//! The plant core without IPC: timing contract, watchdog brakes, saturation,
//! hard stops, delay, and the integrator's physics.

use dkrrt_model::{ArmModel, JVec, NJ};
use dkrrt_sim::plant::{Plant, PlantConfig};

fn cfg() -> PlantConfig {
    PlantConfig {
        dt: 1e-3,
        substeps: 1,
        noise_q_std: 0.0,
        noise_qd_std: 0.0,
        delay_ticks: 0,
        command_timeout_ticks: 20,
        brake_damping: 200.0,
        seed: 1,
    }
}

const Q0: [f64; NJ] = [0.0, -0.5, 1.0, 0.0, 0.5, 0.0];

#[test]
fn brakes_hold_the_arm_until_commands_flow() {
    let mut p = Plant::new(ArmModel::default_arm(), cfg(), &Q0);
    assert!(p.brake_engaged());
    for _ in 0..10 {
        p.step();
    }
    assert!(p.brake_engaged());
    assert_eq!(p.measured().q, Q0);
}

#[test]
fn a_command_answering_state_k_acts_from_tick_k_plus_1() {
    let mut p = Plant::new(ArmModel::default_arm(), cfg(), &Q0);
    let tau = [5.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    // Command answering state 0, offered during tick 0: not applied over [0, 1].
    p.offer_command(0, &tau);
    assert!(p.has_command_for_current());
    p.step();
    assert_eq!(p.measured().tau, [0.0; NJ], "applied too early");
    assert_eq!(p.measured().qd, [0.0; NJ]);
    // Over [1, 2] it acts.
    p.offer_command(1, &tau);
    p.step();
    let m = p.measured();
    assert_eq!(m.tau, tau);
    assert!(m.qd[0] > 0.0);
    assert!(!m.brake_engaged);
    assert_eq!(p.stats.commands_applied, 1);
}

#[test]
fn stale_commands_are_dropped_and_counted() {
    let mut p = Plant::new(ArmModel::default_arm(), cfg(), &Q0);
    for k in 0..5 {
        p.offer_command(k, &[0.0; NJ]);
        p.step();
    }
    p.offer_command(2, &[1.0; NJ]);
    assert_eq!(p.stats.commands_late, 1);
}

#[test]
fn the_watchdog_engages_the_brakes_and_stops_the_arm() {
    let mut p = Plant::new(ArmModel::default_arm(), cfg(), &Q0);
    // Spin joint 0 up for 0.5 s.
    for k in 0..500 {
        p.offer_command(k, &[50.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        p.step();
    }
    let v0 = p.true_state().1[0];
    assert!(v0 > 0.01, "{v0}");
    // Commands stop: after the timeout the brakes engage and stop the arm.
    for _ in 0..21 {
        p.step();
    }
    assert!(p.brake_engaged());
    assert_eq!(p.stats.brake_engagements, 1);
    // Braking only removes energy: kinetic energy falls monotonically.
    let model = p.model().clone();
    let energy = |p: &Plant| {
        let (q, qd) = p.true_state();
        model.kinetic_energy(&q, &qd)
    };
    let e_start = energy(&p);
    let mut e = e_start;
    for _ in 0..30 {
        for _ in 0..100 {
            p.step();
        }
        let e1 = energy(&p);
        // (Zero once every joint is locked.)
        assert!(e1 < e || e1 == 0.0, "{e1} >= {e}");
        e = e1;
    }
    assert!(e < 0.05 * e_start, "{e} vs {e_start}");
}

#[test]
fn torques_beyond_the_limits_saturate() {
    let mut p = Plant::new(ArmModel::default_arm(), cfg(), &Q0);
    let lim = p.model().limits().tau_max;
    p.offer_command(0, &[1e6; NJ]);
    p.step();
    p.offer_command(1, &[1e6; NJ]);
    p.step();
    let m = p.measured();
    for i in 0..NJ {
        assert_eq!(m.tau[i], lim[i]);
    }
    assert!(p.stats.saturations >= 1);
}

#[test]
fn joints_stop_at_their_hard_limits() {
    let model = ArmModel::default_arm();
    let qmax = model.limits().q_max;
    let mut q0 = Q0;
    q0[3] = qmax[3] - 0.001;
    let mut p = Plant::new(model, cfg(), &q0);
    for k in 0..200 {
        p.offer_command(k, &[0.0, 0.0, 0.0, 60.0, 0.0, 0.0]);
        p.step();
    }
    let (q, qd) = p.true_state();
    assert!(q[3] <= qmax[3]);
    assert!(qd[3] <= 0.0);
    assert!(p.stats.limit_hits > 0);
}

#[test]
fn free_motion_conserves_kinetic_energy() {
    // Zero gravity, zero torque: T = ½ q̇ᵀ M q̇ is constant (RK4 error only).
    let model = ArmModel::default_arm();
    let mut p = Plant::new(model.clone(), cfg(), &Q0);
    // Give it a velocity with a short torque pulse, then coast.
    for k in 0..100 {
        p.offer_command(k, &[4.0, -3.0, 2.0, 1.0, -1.0, 0.6]);
        p.step();
    }
    for k in 100..103 {
        p.offer_command(k, &[0.0; NJ]);
        p.step();
    }
    let (q, qd) = p.true_state();
    let e0 = model.kinetic_energy(&q, &qd);
    assert!(e0 > 1e-4, "{e0}");
    for k in 103..1103 {
        p.offer_command(k, &[0.0; NJ]);
        p.step();
    }
    let (q, qd) = p.true_state();
    let e1 = model.kinetic_energy(&q, &qd);
    assert_eq!(p.stats.limit_hits, 0, "the test motion must stay inside the joint range");
    assert!(((e1 - e0) / e0).abs() < 1e-8, "{e0} -> {e1}");
}

#[test]
fn measurement_delay_reports_old_states() {
    let mut c = cfg();
    c.delay_ticks = 5;
    let mut delayed = Plant::new(ArmModel::default_arm(), c, &Q0);
    let mut direct = Plant::new(ArmModel::default_arm(), cfg(), &Q0);
    let mut trace = Vec::new();
    for k in 0..50 {
        for p in [&mut delayed, &mut direct] {
            p.offer_command(k, &[10.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
            p.step();
        }
        trace.push(direct.measured().q);
        if k >= 5 {
            assert_eq!(delayed.measured().q, trace[k as usize - 5], "tick {k}");
        }
    }
}

#[test]
fn noise_is_seeded_and_has_the_configured_spread() {
    let mut c = cfg();
    c.noise_q_std = 1e-3;
    let run = |c: PlantConfig| {
        let mut p = Plant::new(ArmModel::default_arm(), c, &Q0);
        (0..2000).map(|_| p.measured().q[0] - Q0[0]).collect::<Vec<_>>()
    };
    let a = run(c);
    assert_eq!(a, run(c), "same seed, same noise");
    let sd = (a.iter().map(|x| x * x).sum::<f64>() / a.len() as f64).sqrt();
    assert!((sd - 1e-3).abs() < 1e-4, "{sd}");
}

#[test]
fn step_allocates_nothing() {
    let mut p = Plant::new(ArmModel::default_arm(), cfg(), &Q0);
    let (_, s) = dkrrt_rt::alloc_count::count(|| {
        for k in 0..1000 {
            p.offer_command(k, &[1.0; NJ]);
            p.step();
            let _ = p.measured();
        }
        for _ in 0..100 {
            p.step(); // braked (the watchdog): the substeps the brake needs
        }
    });
    assert!(p.brake_engaged());
    assert_eq!(s.allocs, 0, "{s:?}");
    let _ = JVec::zeros();
}

#[global_allocator]
static ALLOC: dkrrt_rt::alloc_count::CountingAlloc = dkrrt_rt::alloc_count::CountingAlloc;

#[test]
fn engaged_brakes_lock_a_slow_joint_and_the_plant_tracks_its_peak_speed() {
    let mut p = Plant::new(ArmModel::default_arm(), cfg(), &Q0);
    for k in 0..500 {
        p.offer_command(k, &[50.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        p.step();
    }
    let moving = p.max_speed();
    assert!(moving > 0.01, "{moving}");
    // The peak speed over the limit, per joint: at least the fastest joint now over the
    // largest limit.
    let v_max = p.model().limits().v_max.amax();
    assert!(p.stats.max_velocity_ratio >= moving / v_max - 1e-12, "peak speed tracked");
    for _ in 0..5000 {
        p.step(); // no commands: the watchdog engages the brakes
    }
    assert!(p.brake_engaged());
    assert_eq!(p.stats.brake_engagements, 1);
    assert_eq!(p.max_speed(), 0.0, "a braked joint below the lock speed is held at rest");
    assert_eq!(p.stats.non_finite_steps, 0);
}

#[test]
fn a_non_finite_step_never_becomes_a_state() {
    let mut p = Plant::new(ArmModel::default_arm(), cfg(), &Q0);
    for k in 0..5 {
        p.offer_command(k, &[1.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        p.step();
    }
    let (q_before, _) = p.true_state();
    // A torque that makes the integration blow up (the validators keep NaN off the bus; the
    // plant does not rely on it).
    p.offer_command(5, &[f64::NAN, 0.0, 0.0, 0.0, 0.0, 0.0]);
    p.step();
    p.step();
    let (q, qd) = p.true_state();
    assert!(q.iter().chain(qd.iter()).all(|x| x.is_finite()), "{q} {qd}");
    assert!(p.stats.non_finite_steps > 0);
    assert!(p.brake_engaged(), "a blown-up step engages the brakes");
    assert!((q - q_before).amax() < 1e-3);
}

#[test]
fn one_rk4_step_per_tick_matches_a_fine_integration_and_the_brake_stays_stable() {
    // The free arm under a varying torque: 1 substep per 1 ms tick vs 16.
    let run = |substeps: u32| {
        let mut p = Plant::new(ArmModel::default_arm(), PlantConfig { substeps, ..cfg() }, &Q0);
        for k in 0..2000u64 {
            let s = (k as f64 * 0.003).sin();
            p.offer_command(k, &[4.0 * s, -3.0 * s, 2.0, 0.5 * s, -0.5, 0.3 * s]);
            p.step();
        }
        p.true_state()
    };
    let ((q1, v1), (q16, v16)) = (run(1), run(16));
    assert!(
        (q1 - q16).amax() < 1e-9 && (v1 - v16).amax() < 1e-8,
        "{} {}",
        (q1 - q16).amax(),
        (v1 - v16).amax()
    );
    assert!(v16.amax() > 0.05, "the arm moved: {}", v16.amax());
    // A viscous brake is stiff: at 1000 N·m·s/rad, one RK4 step per tick would diverge in the
    // lightest mode (h·c/λ_min(M) well over 2.8). The plant subdivides while braked: the arm
    // comes to rest as with 64 substeps, never faster than when the brake engaged.
    let brake = |substeps: u32| {
        let c = PlantConfig { substeps, brake_damping: 1000.0, ..cfg() };
        let mut p = Plant::new(ArmModel::default_arm(), c, &Q0);
        for k in 0..300 {
            p.offer_command(k, &[0.0, 0.0, 0.0, 2.0, 2.0, 2.0]);
            p.step();
        }
        for _ in 0..21 {
            p.step(); // the last command holds until the watchdog's timeout
        }
        assert!(p.brake_engaged());
        let v0 = p.max_speed();
        assert!(v0 > 0.05, "{v0}");
        for _ in 0..400 {
            p.step();
            assert!(p.max_speed() <= v0 + 1e-12, "{} > {v0}", p.max_speed());
        }
        assert!(p.max_speed() == 0.0 && p.stats.non_finite_steps == 0);
        p.true_state().0
    };
    let (b1, b16) = (brake(1), brake(64));
    assert!((b1 - b16).amax() < 1e-4, "{}", (b1 - b16).amax());
}

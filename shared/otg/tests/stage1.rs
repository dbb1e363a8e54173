//! Known-value and randomized tests for rest-to-rest motion, time
//! synchronization and the velocity interface (brake to rest).

mod common;

use common::check_traj;
use dkrrt_otg::{KinState, Limits, Options, OtgError, Sync, Trajectory};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

fn one(d: f64, v: f64, a: f64, j: f64) -> f64 {
    let lim = Limits { v_max: [v], a_max: [a], j_max: [j] };
    let tr = Trajectory::calculate(&KinState::rest([0.0]), &KinState::rest([d]), &lim, &Options::default())
        .unwrap();
    check_traj(&tr, &KinState::rest([0.0]), &KinState::rest([d]), &lim, true, 500, false).unwrap();
    tr.duration()
}

/// Hand-derived: V=1, A=1, J=1, D=10: ramp 0→1 takes 2 s (covering 1), so
/// both ramps cover 2 and the cruise lasts 8 s: T = 12.
#[test]
fn velocity_limit_reached_no_acc_plateau() {
    assert!((one(10.0, 1.0, 1.0, 1.0) - 12.0).abs() < 1e-12);
    assert!((one(-10.0, 1.0, 1.0, 1.0) - 12.0).abs() < 1e-12);
}

/// V=2, A=1, J=2, D=10: ramp = 0.5 s jerk + 1.5 s at A + 0.5 s jerk (2.5 s,
/// covering 2.5); two ramps cover 5, cruise 2.5 s: T = 7.5.
#[test]
fn velocity_and_acceleration_limit_reached() {
    assert!((one(10.0, 2.0, 1.0, 2.0) - 7.5).abs() < 1e-12);
}

/// V=10, A=10, J=1, D=2: no limit reached; peak velocity vc with
/// vc·2√(vc/J) = D → vc = 1, four 1 s jerk phases: T = 4.
#[test]
fn no_limit_reached() {
    assert!((one(2.0, 10.0, 10.0, 1.0) - 4.0).abs() < 1e-12);
}

/// V=10, A=1, J=1, D=6: vc²/A + vc·A/J = 6 → vc = 2; ramp = 1 + 1 + 1 s: T = 6.
#[test]
fn acceleration_limit_reached_only() {
    assert!((one(6.0, 10.0, 1.0, 1.0) - 6.0).abs() < 1e-12);
}

#[test]
fn zero_distance_is_zero_duration() {
    assert_eq!(one(0.0, 1.0, 1.0, 1.0), 0.0);
}

/// The slow joint (T = 12) sets the duration; the other joint is stretched.
#[test]
fn time_synchronization_stretches_faster_joint() {
    let lim = Limits { v_max: [1.0, 1.0], a_max: [1.0, 1.0], j_max: [1.0, 1.0] };
    let start = KinState::rest([0.0, 0.0]);
    let target = KinState::rest([10.0, -1.0]);
    let tr = Trajectory::calculate(&start, &target, &lim, &Options::default()).unwrap();
    assert!((tr.duration() - 12.0).abs() < 1e-12);
    check_traj(&tr, &start, &target, &lim, true, 2000, false).unwrap();
    // Joint 1 is still moving half-way (not finished early).
    assert!(tr.at(6.0).v[1].abs() > 1e-3);
    let ex = tr.position_extrema();
    assert!((ex[0].max - 10.0).abs() < 1e-9 && ex[0].min.abs() < 1e-12);
    assert!((ex[1].min + 1.0).abs() < 1e-9);
}

#[test]
fn options_min_duration_and_period() {
    let lim = Limits { v_max: [1.0], a_max: [1.0], j_max: [1.0] };
    let (s, t) = (KinState::rest([0.0]), KinState::rest([10.0]));
    let o = Options { min_duration: Some(20.0), ..Options::default() };
    let tr = Trajectory::calculate(&s, &t, &lim, &o).unwrap();
    assert!((tr.duration() - 20.0).abs() < 1e-12);
    check_traj(&tr, &s, &t, &lim, true, 1000, false).unwrap();
    let o = Options { period: Some(0.7), ..Options::default() };
    let tr = Trajectory::calculate(&s, &t, &lim, &o).unwrap();
    assert!((tr.duration() - 18.0 * 0.7).abs() < 1e-9, "{}", tr.duration());
    check_traj(&tr, &s, &t, &lim, true, 1000, false).unwrap();
}

/// Brake to rest from v = 1, a = 0 (A = J = 1): ramp to −1 in 1 s and back in 1 s: T = 2.
#[test]
fn brake_to_rest_known() {
    let lim = Limits { v_max: [2.0], a_max: [1.0], j_max: [1.0] };
    let s = KinState { p: [0.0], v: [1.0], a: [0.0] };
    let tr = Trajectory::calculate_velocity(&s, &[0.0], &[0.0], &lim, &Options::default()).unwrap();
    assert!((tr.duration() - 2.0).abs() < 1e-12);
    // Distance: symmetric, 1 m/s average over 2 s... exactly v0·T/2 = 1.
    assert!((tr.at(2.0).p[0] - 1.0).abs() < 1e-12);
}

/// a0 = 3 beyond A = 1 (J = 1, v0 = 0): 2 s brake to a = 1 (v = 4), then ramp to
/// −1 (2 s, Δv = 0), hold −1 for 3.5 s, ramp to 0 (1 s, Δv = −0.5): T = 8.5.
#[test]
fn brake_to_rest_from_beyond_acceleration_limit() {
    let lim = Limits { v_max: [10.0], a_max: [1.0], j_max: [1.0] };
    let s = KinState { p: [0.0], v: [0.0], a: [3.0] };
    let tr = Trajectory::calculate_velocity(&s, &[0.0], &[0.0], &lim, &Options::default()).unwrap();
    assert!((tr.duration() - 8.5).abs() < 1e-12, "{}", tr.duration());
    let e = tr.at(tr.duration());
    assert!(e.v[0].abs() < 1e-12 && e.a[0].abs() < 1e-12);
}

#[test]
fn bad_input_is_an_error() {
    let lim = Limits { v_max: [1.0, 1.0], a_max: [1.0, 1.0], j_max: [1.0, 1.0] };
    let s = KinState::rest([0.0, 0.0]);
    let o = Options::default();
    let mut bad = lim;
    bad.j_max[1] = f64::NAN;
    assert!(matches!(
        Trajectory::calculate(&s, &KinState::rest([1.0, 1.0]), &bad, &o),
        Err(OtgError::InvalidLimit { joint: 1, .. })
    ));
    bad = lim;
    bad.a_max[0] = 0.0;
    assert!(matches!(
        Trajectory::calculate_velocity(&s, &[0.0; 2], &[0.0; 2], &bad, &o),
        Err(OtgError::InvalidLimit { joint: 0, .. })
    ));
    let mut ns = s;
    ns.v[1] = f64::NAN;
    assert!(matches!(
        Trajectory::calculate(&ns, &KinState::rest([1.0, 1.0]), &lim, &o),
        Err(OtgError::NonFiniteState { joint: 1, .. })
    ));
    let t = KinState { p: [1.0, 1.0], v: [2.0, 0.0], a: [0.0, 0.0] };
    assert!(matches!(
        Trajectory::calculate(&s, &t, &lim, &o),
        Err(OtgError::TargetVelocityBeyondLimit { joint: 0, .. })
    ));
    let t = KinState { p: [1.0, 1.0], v: [0.0, 0.0], a: [0.0, -1.5] };
    assert!(matches!(
        Trajectory::calculate(&s, &t, &lim, &o),
        Err(OtgError::TargetAccelerationBeyondLimit { joint: 1, .. })
    ));
    // Arriving at v = 0.9 with a = −0.8 needs v = 0.9 + 0.32 > 1 just before.
    let t = KinState { p: [1.0, 1.0], v: [0.9, 0.0], a: [-0.8, 0.0] };
    assert!(matches!(
        Trajectory::calculate(&s, &t, &lim, &o),
        Err(OtgError::UnreachableTargetAcceleration { joint: 0, .. })
    ));
    let o2 = Options { period: Some(-1.0), ..o };
    assert!(matches!(
        Trajectory::calculate(&s, &KinState::rest([1.0, 1.0]), &lim, &o2),
        Err(OtgError::InvalidOption { .. })
    ));
}

fn rand_limits<const N: usize>(rng: &mut SmallRng) -> Limits<N> {
    let mut l = Limits { v_max: [0.0; N], a_max: [0.0; N], j_max: [0.0; N] };
    for j in 0..N {
        l.v_max[j] = rng.random_range(0.08..16.0);
        l.a_max[j] = rng.random_range(0.08..16.0);
        l.j_max[j] = rng.random_range(0.08..16.0);
    }
    l
}

/// Random rest-to-rest problems (7 joints), all syncs.
#[test]
fn random_rest_to_rest() {
    let mut rng = SmallRng::seed_from_u64(1);
    for i in 0..3000 {
        let lim = rand_limits::<7>(&mut rng);
        let mut s = KinState::rest([0.0; 7]);
        let mut t = KinState::rest([0.0; 7]);
        for j in 0..7 {
            s.p[j] = rng.random_range(-4.0..4.0);
            t.p[j] = if rng.random_bool(0.1) { s.p[j] } else { rng.random_range(-4.0..4.0) };
        }
        let sync = if i % 5 == 0 { Sync::None } else { Sync::Time };
        let o = Options { sync, ..Options::default() };
        let tr = Trajectory::calculate(&s, &t, &lim, &o).unwrap();
        check_traj(&tr, &s, &t, &lim, true, 200, false).unwrap_or_else(|e| panic!("problem {i}: {e}"));
    }
}

/// Random brake-to-rest (velocity interface), including states beyond the limits.
#[test]
fn random_brake_to_rest() {
    let mut rng = SmallRng::seed_from_u64(2);
    for i in 0..3000 {
        let lim = rand_limits::<6>(&mut rng);
        let mut s = KinState::rest([0.0; 6]);
        for j in 0..6 {
            s.p[j] = rng.random_range(-4.0..4.0);
            s.v[j] = rng.random_range(-1.0..1.0) * lim.v_max[j];
            s.a[j] = rng.random_range(-1.5..1.5) * lim.a_max[j];
        }
        let tr = Trajectory::calculate_velocity(&s, &[0.0; 6], &[0.0; 6], &lim, &Options::default())
            .unwrap_or_else(|e| panic!("problem {i}: {e}"));
        let e = tr.at(tr.duration());
        for j in 0..6 {
            assert!(e.v[j].abs() < 1e-8 && e.a[j].abs() < 1e-10, "problem {i} joint {j}");
            // All joints end together: each joint is still moving (or already at rest) until the end.
            let last = tr.joint_segments(j).last().unwrap();
            assert!((last.t1 - tr.duration()).abs() < 1e-12);
            // Acceleration within limits after the brake: sample densely.
        }
        for k in 0..=200 {
            let t = tr.duration() * k as f64 / 200.0;
            let sm = tr.at(t);
            for j in 0..6 {
                let a_bound = lim.a_max[j].max(s.a[j].abs()) * (1.0 + 1e-9);
                assert!(sm.a[j].abs() <= a_bound, "problem {i} joint {j} t={t}");
            }
        }
    }
}

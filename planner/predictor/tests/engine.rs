//! The fused roll-out of [`Engine`] equals the reference relift roll-out of
//! `dkrrt_koopman::Forecaster` (translation and attitude models separately) up to rounding.

mod common;

use common::{fitted, fitted_deep, free_rods};
use dkrrt_debris::SensorConfig;
use dkrrt_deep::TrainConfig;
use dkrrt_koopman::debris_state::{N, ROT, TRANS};
use dkrrt_koopman::{Forecaster, Rollout, StateConstraint};
use dkrrt_predictor::eval::record;
use dkrrt_predictor::models::{Engine, Job};
use dkrrt_predictor::training::{train_models, TrainOptions, TrainedModels};
use dkrrt_predictor::{Method, Models};

#[test]
fn engine_equals_reference_relift() {
    let rec = record(&free_rods(7), SensorConfig::default(), 4.0, 0.01, 7).unwrap();
    // True states of every object at a few instants as start states.
    let starts: Vec<[f64; N]> =
        (0..4).flat_map(|k| rec.truth.frames[k * 100].iter().map(|(_, x)| *x)).collect();
    assert!(starts.len() >= 16);
    for method in [Method::EdmdPoly, Method::EdmdRbf, Method::KoopmanOnline, Method::DualData] {
        let m = fitted(method);
        let h = m.horizon;
        let mut eng = Engine::new(&m);
        let mut ft = Forecaster::new(m.trans.p);
        let mut fa = Forecaster::new(m.att.p).with_constraint(StateConstraint::UnitQuaternion { at: 0 });
        let (mut out, mut tb, mut ab) = (vec![0.0; h * N], vec![0.0; h * 6], vec![0.0; h * 7]);
        let mut worst: f64 = 0.0;
        for x0 in &starts {
            eng.run(&m, &m.trans, &m.att, x0, h, &mut out);
            ft.forecast(&m.trans, &m.trans_lift, &x0[TRANS], &[], Rollout::Relift, &mut tb);
            fa.forecast(&m.att, &m.att_lift, &x0[ROT], &[], Rollout::Relift, &mut ab);
            for k in 0..h {
                let o = &out[k * N..(k + 1) * N];
                for i in 0..6 {
                    worst = worst.max((o[i] - tb[k * 6 + i]).abs() / (1.0 + tb[k * 6 + i].abs()));
                }
                for i in 0..7 {
                    worst = worst.max((o[6 + i] - ab[k * 7 + i]).abs() / (1.0 + ab[k * 7 + i].abs()));
                }
            }
        }
        assert_eq!(eng.fallbacks, 0, "{method:?}: true states left the trust region");
        assert!(worst < 1e-9, "{method:?}: max relative deviation {worst:e}");
        eprintln!("{method:?}: max relative deviation {worst:e}");
    }
}

/// Deep methods (linear lifted roll-out of the attitude): the engine equals the reference
/// `Forecaster` roll-outs (translation relift, attitude linear with the decoded quaternion
/// renormalised), for the tiny (p = 15, padded to 16) and the default network size (p = 23,
/// padded to 24).
#[test]
fn engine_equals_reference_linear_deep() {
    let rec = record(&free_rods(7), SensorConfig::default(), 4.0, 0.01, 7).unwrap();
    let starts: Vec<[f64; N]> =
        (0..4).flat_map(|k| rec.truth.frames[k * 100].iter().map(|(_, x)| *x)).collect();
    for deep in deep_models() {
        for method in [Method::DeepKoopman, Method::DeepKoopmanOnline] {
            let m = fitted_deep(method, &deep.attitude);
            assert_eq!(m.att_rollout, Rollout::Linear);
            let h = m.horizon;
            let mut eng = Engine::new(&m);
            let mut ft = Forecaster::new(m.trans.p);
            let mut fa = Forecaster::new(m.att.p).with_constraint(StateConstraint::UnitQuaternion { at: 0 });
            let (mut out, mut tb, mut ab) = (vec![0.0; h * N], vec![0.0; h * 6], vec![0.0; h * 7]);
            let mut worst: f64 = 0.0;
            for x0 in &starts {
                eng.run(&m, &m.trans, &m.att, x0, h, &mut out);
                ft.forecast(&m.trans, &m.trans_lift, &x0[TRANS], &[], Rollout::Relift, &mut tb);
                fa.forecast(&m.att, &m.att_lift, &x0[ROT], &[], Rollout::Linear, &mut ab);
                // Compare up to the first fallback step (an untrained model may leave the
                // trust region).
                for k in 0..h {
                    let o = &out[k * N..(k + 1) * N];
                    let r: Vec<f64> =
                        tb[k * 6..(k + 1) * 6].iter().chain(&ab[k * 7..(k + 1) * 7]).copied().collect();
                    if !r.iter().all(|v| v.is_finite()) || r[3..6].iter().map(|v| v * v).sum::<f64>() > 25.0 {
                        break;
                    }
                    if r[10..13].iter().map(|v| v * v).sum::<f64>() > 225.0 {
                        break;
                    }
                    for i in 0..N {
                        worst = worst.max((o[i] - r[i]).abs() / (1.0 + r[i].abs()));
                    }
                }
            }
            assert!(worst < 1e-9, "{method:?} p = {}: max relative deviation {worst:e}", m.att.p);
            eprintln!("{method:?} p = {}: max relative deviation {worst:e}", m.att.p);
        }
    }
}

/// Deep models of the tiny size and of the default size (2 epochs: the cost and the code
/// paths depend on the sizes only).
fn deep_models() -> Vec<TrainedModels> {
    let tiny = train_models(&TrainOptions::tiny(), &mut |_| {}).unwrap();
    let d = TrainOptions::default().deep;
    let o = TrainOptions { deep: TrainConfig { epochs: 2, ..d }, ..TrainOptions::tiny() };
    vec![tiny, train_models(&o, &mut |_| {}).unwrap()]
}

/// The AVX2 code path (where the CPU has it) and the portable path give bit-identical
/// forecasts, and so do the lockstep roll-outs of 2, 3 and 4 tracks (`run2`, `run_lanes`) and
/// single `run`s, for every method, including starts that leave the trust region
/// (constant-velocity fallback).
#[test]
fn code_paths_and_lanes_are_bit_identical() {
    let rec = record(&free_rods(7), SensorConfig::default(), 4.0, 0.01, 7).unwrap();
    let mut starts: Vec<[f64; N]> =
        (0..4).flat_map(|k| rec.truth.frames[k * 100].iter().map(|(_, x)| *x)).collect();
    // Implausible starts: fast spin, fast drift, NaN.
    let mut s = starts[0];
    s[10] = 40.0;
    starts.push(s);
    let mut s = starts[1];
    s[3] = 9.0;
    starts.push(s);
    let mut s = starts[2];
    s[12] = f64::NAN;
    starts.push(s);
    while !starts.len().is_multiple_of(4) {
        starts.push(starts[3]);
    }
    let deep = deep_models();
    let mut all: Vec<Models> = Method::CLASSIC
        .iter()
        .map(|&m| {
            if m == Method::ConstantVelocity {
                Models::constant_velocity(0.1, 40, rec.mean_motion, 0.05, 0.05)
            } else {
                fitted(m)
            }
        })
        .collect();
    for d in &deep {
        all.push(fitted_deep(Method::DeepKoopman, &d.attitude));
    }
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<u64>>();
    for m in &all {
        let h = m.horizon;
        let mut fast = Engine::new(m);
        let mut port = Engine::new(m);
        port.portable = true;
        let mut single = Engine::new(m);
        let mut want = vec![vec![0.0; h * N]; 4];
        let mut got = vec![vec![0.0; h * N]; 4];
        for p in starts.chunks_exact(4) {
            for (x0, o) in p.iter().zip(&mut want) {
                single.run(m, &m.trans, &m.att, x0, h, o);
            }
            for eng in [&mut fast, &mut port] {
                // One track on the other path, then 2, 3 and 4 in lockstep.
                let [g0, g1, ..] = &mut got[..] else { unreachable!() };
                eng.run(m, &m.trans, &m.att, &p[0], h, g0);
                assert_eq!(bits(&want[0]), bits(g0), "{:?}: run differs between paths", m.method);
                eng.run2(m, job(m, &p[0], g0), job(m, &p[1], g1), h);
                for t in 0..2 {
                    assert_eq!(bits(&want[t]), bits(&got[t]), "{:?}: run2 lane {t} differs", m.method);
                }
                let [g0, g1, g2, _] = &mut got[..] else { unreachable!() };
                eng.run_lanes::<3>(m, [job(m, &p[0], g0), job(m, &p[1], g1), job(m, &p[2], g2)], h);
                for t in 0..3 {
                    assert_eq!(bits(&want[t]), bits(&got[t]), "{:?}: 3 lanes, lane {t} differs", m.method);
                }
                let [g0, g1, g2, g3] = &mut got[..] else { unreachable!() };
                eng.run_lanes::<4>(
                    m,
                    [job(m, &p[0], g0), job(m, &p[1], g1), job(m, &p[2], g2), job(m, &p[3], g3)],
                    h,
                );
                for t in 0..4 {
                    assert_eq!(bits(&want[t]), bits(&got[t]), "{:?}: 4 lanes, lane {t} differs", m.method);
                }
            }
        }
        assert_eq!(fast.fallbacks, port.fallbacks);
        if m.method != Method::ConstantVelocity {
            assert!(fast.fallbacks >= 3, "{:?}: {} fallbacks", m.method, fast.fallbacks);
        }
    }
}

fn job<'a>(m: &'a Models, x0: &'a [f64], out: &'a mut [f64]) -> Job<'a> {
    Job { trans: &m.trans, att: &m.att, x0, out }
}

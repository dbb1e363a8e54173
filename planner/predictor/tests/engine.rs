//! The fused roll-out of [`Engine`] equals the reference relift roll-out of
//! `dkrrt_koopman::Forecaster` (translation and attitude models separately) up to rounding.

mod common;

use common::{fitted, free_rods};
use dkrrt_debris::SensorConfig;
use dkrrt_koopman::debris_state::{N, ROT, TRANS};
use dkrrt_koopman::{Forecaster, Rollout, StateConstraint};
use dkrrt_predictor::eval::record;
use dkrrt_predictor::models::Engine;
use dkrrt_predictor::Method;

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

//! Planner benchmarks: one configuration checked against 32 forecast tracks (interpolation +
//! inflation + distances), the first plan in free space, and a plan around a crossing
//! obstacle (first solution, then the default improvement iterations).

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use dkrrt_model::{ArmModel, NJ};
use dkrrt_msg::{DebrisForecast, DebrisShape, ForecastStep, Trajectory, Zeroed};
use dkrrt_otg::{KinState, Limits};
use dkrrt_rrt::*;

const START: [f64; NJ] = [0.0, -0.5, 1.0, 0.0, 0.5, 0.0];
const GOAL: [f64; NJ] = [0.35, -0.2, 0.7, 0.3, 0.2, 0.4];

fn limits() -> Limits<NJ> {
    Limits {
        v_max: [0.1, 0.1, 0.1, 0.18, 0.18, 0.18],
        a_max: [0.2, 0.2, 0.2, 0.4, 0.4, 0.4],
        j_max: [1.0, 1.0, 1.0, 2.0, 2.0, 2.0],
    }
}

/// 32 tracks of mixed shapes drifting around the arm at 2–6 m.
fn field() -> Box<DebrisForecast> {
    let mut f = Box::new(<DebrisForecast as Zeroed>::zeroed());
    f.count = 32;
    f.steps = 40;
    f.dt_s = 0.1;
    for i in 0..32 {
        let a = i as f64 * 0.7;
        let r = 2.0 + (i % 5) as f64;
        let tr = &mut f.tracks[i];
        tr.id = i as u32;
        tr.shape = match i % 3 {
            0 => DebrisShape::sphere(0.2),
            1 => DebrisShape::capsule(0.5, 0.04),
            _ => DebrisShape::cuboid([0.3, 0.2, 0.01], [0.0; 3]),
        };
        tr.bounding_radius = tr.shape.bounding_radius();
        for k in 0..40 {
            let t = 0.1 * (k + 1) as f64;
            let h = 0.5 * (0.3 * t + a).sin();
            tr.steps[k] = ForecastStep {
                p: [r * a.cos() + 0.05 * t, r * a.sin() - 0.05 * t, (i % 4) as f64 - 1.5],
                q: [h.cos(), h.sin(), 0.0, 0.0],
                sigma_m: 0.01 + 0.02 * t,
                sigma_pos_m: 0.01 + 0.01 * t,
            };
        }
    }
    f
}

fn bench(c: &mut Criterion) {
    let f = field();
    let mut w = WorldInTime::new(0.05);
    w.load_forecast(&f);
    let mut ch = Checker::new(ArmModel::default_arm(), &limits().v_max, 0.03);
    let mut k = 0u32;
    c.bench_function("config_vs_32_forecast_tracks", |b| {
        b.iter(|| {
            k = k.wrapping_add(1);
            let s = (k % 100) as f64 * 0.01;
            let q = [s, -0.5 + s, 1.0 - s, s, 0.5, -s];
            black_box(ch.clearance_at(&w, &q, 1.0 + s, 0.015, 0.0))
        })
    });
    let mut p = Planner::new(ArmModel::default_arm(), limits(), PlannerConfig::default());
    let mut out = Box::new(<Trajectory as Zeroed>::zeroed());
    let req = Request { start: KinState::rest(START), t0: 0.0, goal: GOAL };
    c.bench_function("plan_32_tracks_first_solution_and_improvement", |b| {
        b.iter(|| black_box(p.plan(&req, &w, 300, || true, 1, &mut out)))
    });
    let empty = WorldInTime::new(0.05);
    c.bench_function("plan_free_space", |b| {
        b.iter(|| black_box(p.plan(&req, &empty, 300, || true, 1, &mut out)))
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);

//! How close to time-optimal are waypoint trajectories?
//!
//! `cargo run --release -p dkrrt-otg --example waypoints_compare [problems]`
//!
//! Random 7-joint planner-like paths (rest at both ends, 2–6 intermediate
//! waypoints, each a random step of N(0.6, 0.5) per joint from the previous
//! one, so joints mostly keep their direction with some reversals). Compared:
//! * lower bound: the time-optimal direct motion start → target, ignoring the
//!   waypoints (any trajectory through them takes at least this long),
//! * ours (`Trajectory::calculate_waypoints`),
//! * stopping at every waypoint (synchronized rest-to-rest sections),
//! * rsruckig's local pass-through waypoint solver (`intermediate_positions`).

#![allow(clippy::needless_range_loop)]

use dkrrt_otg::{KinState, Limits, Options, Trajectory};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use rsruckig::prelude::*;

const N: usize = 7;

fn normal(rng: &mut SmallRng, m: f64, sd: f64) -> f64 {
    let u1: f64 = rng.random_range(f64::EPSILON..1.0);
    let u2: f64 = rng.random();
    m + sd * (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

fn main() {
    let n: usize = std::env::args().nth(1).and_then(|a| a.parse().ok()).unwrap_or(500);
    let mut rng = SmallRng::seed_from_u64(5);
    let o = Options::default();
    let (mut r_ours, mut r_stop, mut r_rs) = (Vec::new(), Vec::new(), Vec::new());
    let mut rs_fail = 0;
    let mut ours_fail = 0;
    let mut better_than_rs = 0;
    let mut otg = Ruckig::<N, ThrowErrorHandler>::with_waypoints(None, 0.001, 8);
    let mut traj = rsruckig::prelude::Trajectory::new(None);
    for _ in 0..n {
        let mut l = Limits { v_max: [0.0; N], a_max: [0.0; N], j_max: [0.0; N] };
        for j in 0..N {
            l.v_max[j] = rng.random_range(0.5..3.0);
            l.a_max[j] = rng.random_range(1.0..6.0);
            l.j_max[j] = rng.random_range(5.0..40.0);
        }
        let k = rng.random_range(2..=6);
        let mut pts = vec![[0.0; N]];
        for _ in 0..=k {
            let mut p = *pts.last().unwrap();
            for v in p.iter_mut() {
                *v += normal(&mut rng, 0.6, 0.5);
            }
            pts.push(p);
        }
        let start = KinState::rest(pts[0]);
        let target = KinState::rest(pts[k + 1]);
        let wps = &pts[1..=k];
        let lb = Trajectory::calculate(&start, &target, &l, &o).unwrap().duration();
        let ours = match Trajectory::calculate_waypoints(&start, wps, &target, &l, &o) {
            Ok(t) => t.duration(),
            Err(_) => {
                ours_fail += 1;
                continue;
            }
        };
        let mut stop = 0.0;
        for w in pts.windows(2) {
            stop += Trajectory::calculate(&KinState::rest(w[0]), &KinState::rest(w[1]), &l, &o)
                .unwrap()
                .duration();
        }
        let mut input = InputParameter::<N>::with_waypoints(None, 8);
        for j in 0..N {
            input.current_position[j] = pts[0][j];
            input.target_position[j] = pts[k + 1][j];
            input.max_velocity[j] = l.v_max[j];
            input.max_acceleration[j] = l.a_max[j];
            input.max_jerk[j] = l.j_max[j];
        }
        for w in wps {
            let mut d = DataArrayOrVec::<f64, N>::new(None, 0.0);
            for j in 0..N {
                d[j] = w[j];
            }
            input.intermediate_positions.push(d);
        }
        match otg.calculate(&input, &mut traj) {
            Ok(_) => {
                let rs = traj.get_duration();
                r_rs.push(rs / lb);
                if ours < rs {
                    better_than_rs += 1;
                }
            }
            Err(_) => rs_fail += 1,
        }
        r_ours.push(ours / lb);
        r_stop.push(stop / lb);
    }
    let stats = |v: &mut Vec<f64>| {
        v.sort_by(|a, b| a.total_cmp(b));
        (v.iter().sum::<f64>() / v.len() as f64, v[v.len() / 2], v[v.len() - 1])
    };
    println!(
        "{} problems (7 joints, 2-6 waypoints); duration / lower bound (direct time-optimal):",
        r_ours.len()
    );
    println!("| method | mean | median | worst |");
    println!("|---|---|---|---|");
    for (name, v) in [
        ("dkrrt-otg waypoints", &mut r_ours),
        ("stop at each waypoint", &mut r_stop),
        ("rsruckig intermediate_positions", &mut r_rs),
    ] {
        let (m, med, w) = stats(v);
        println!("| {name} | {m:.3} | {med:.3} | {w:.3} |");
    }
    println!("ours shorter than rsruckig in {better_than_rs} cases; failures: ours {ours_fail}, rsruckig {rs_fail}");
}

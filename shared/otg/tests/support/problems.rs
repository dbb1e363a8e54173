//! Random problems drawn like Ruckig's own tests, and their rsruckig input.
//! Shared by the oracle test, the criterion bench and the table example
//! (included with `#[path]`).

#![allow(dead_code)]

use dkrrt_otg::{KinState, Limits};
use rand::rngs::SmallRng;
use rand::Rng;
use rsruckig::prelude::InputParameter;

/// N(0, sd²) by Box–Muller.
pub fn normal(rng: &mut SmallRng, sd: f64) -> f64 {
    let u1: f64 = rng.random_range(f64::EPSILON..1.0);
    let u2: f64 = rng.random();
    sd * (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// p ~ N(0, 4), v, a ~ N(0, 0.8) each zeroed with probability `zero_p`,
/// limits ~ U(0.08, 16).
pub fn draw<const N: usize>(rng: &mut SmallRng, zero_p: f64) -> (KinState<N>, KinState<N>, Limits<N>) {
    let mut s = KinState::default();
    let mut t = KinState::default();
    let mut l = Limits { v_max: [0.0; N], a_max: [0.0; N], j_max: [0.0; N] };
    for j in 0..N {
        s.p[j] = normal(rng, 4.0);
        t.p[j] = normal(rng, 4.0);
        s.v[j] = if rng.random_bool(zero_p) { 0.0 } else { normal(rng, 0.8) };
        s.a[j] = if rng.random_bool(zero_p) { 0.0 } else { normal(rng, 0.8) };
        t.v[j] = if rng.random_bool(zero_p) { 0.0 } else { normal(rng, 0.8) };
        t.a[j] = if rng.random_bool(zero_p) { 0.0 } else { normal(rng, 0.8) };
        l.v_max[j] = rng.random_range(0.08..16.0);
        l.a_max[j] = rng.random_range(0.08..16.0);
        l.j_max[j] = rng.random_range(0.08..16.0);
    }
    (s, t, l)
}

/// The same problem as rsruckig's input.
pub fn ruckig_input<const N: usize>(s: &KinState<N>, t: &KinState<N>, l: &Limits<N>) -> InputParameter<N> {
    let mut input = InputParameter::new(None);
    for j in 0..N {
        input.current_position[j] = s.p[j];
        input.current_velocity[j] = s.v[j];
        input.current_acceleration[j] = s.a[j];
        input.target_position[j] = t.p[j];
        input.target_velocity[j] = t.v[j];
        input.target_acceleration[j] = t.a[j];
        input.max_velocity[j] = l.v_max[j];
        input.max_acceleration[j] = l.a_max[j];
        input.max_jerk[j] = l.j_max[j];
    }
    input
}

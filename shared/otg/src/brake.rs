//! Braking pre-trajectories: bring a current state that is beyond the
//! acceleration limit, or that will inevitably exceed the velocity limit, back
//! inside the limits with at most two phases (full jerk, then possibly
//! constant acceleration), before the time-optimal profile starts.

/// Tiny margin so that the post-brake state lies strictly inside the limits.
const EPS: f64 = 2.2e-14;

#[inline]
fn v_at(v0: f64, a0: f64, j: f64, t: f64) -> f64 {
    v0 + t * (a0 + j * t / 2.0)
}

/// Up to two braking phases `(duration, jerk)`; zero durations mean "unused".
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Brake {
    pub t: [f64; 2],
    pub j: [f64; 2],
}

impl Brake {
    pub fn duration(&self) -> f64 {
        self.t[0] + self.t[1]
    }
}

/// Velocity-limit brake (written for the "upper" side; the lower side calls it
/// with mirrored arguments): ramp the acceleration down with jerk `-j` until the
/// velocity is back at the limit, holding the opposite acceleration limit if it
/// is reached first.
fn velocity_brake(v0: f64, a0: f64, vmax: f64, vmin: f64, amin: f64, j: f64) -> Brake {
    let mut b = Brake { t: [0.0; 2], j: [-j, 0.0] };
    let t_to_amin = (a0 - amin) / j;
    let t_to_vmax = a0 / j + (a0 * a0 + 2.0 * j * (v0 - vmax)).sqrt() / j.abs();
    let t_to_vmin = a0 / j + (a0 * a0 / 2.0 + j * (v0 - vmin)).sqrt() / j.abs();
    let t_v = t_to_vmax.min(t_to_vmin);
    if t_to_amin < t_v {
        let v_amin = v_at(v0, a0, -j, t_to_amin);
        let hold_to_vmax = -(v_amin - vmax) / amin;
        let hold_to_vmin = amin / (2.0 * j) - (v_amin - vmin) / amin;
        b.t[0] = (t_to_amin - EPS).max(0.0);
        b.t[1] = hold_to_vmax.min(hold_to_vmin).max(0.0);
    } else {
        b.t[0] = (t_v - EPS).max(0.0);
    }
    b
}

/// Acceleration-limit brake (upper side): ramp the acceleration back to the limit.
fn acceleration_brake(v0: f64, a0: f64, vmax: f64, vmin: f64, amax: f64, amin: f64, j: f64) -> Brake {
    let t_to_amax = (a0 - amax) / j;
    let v_azero = v_at(v0, a0, -j, a0 / j);
    let v_amax = v_at(v0, a0, -j, t_to_amax);
    if (v_azero > vmax && j > 0.0) || (v_azero < vmax && j < 0.0) {
        return velocity_brake(v0, a0, vmax, vmin, amin, j);
    }
    let mut b = Brake { t: [t_to_amax + EPS, 0.0], j: [-j, 0.0] };
    if (v_amax < vmin && j > 0.0) || (v_amax > vmin && j < 0.0) {
        let hold_to_vmin = -(v_amax - vmin) / amax;
        let hold_to_vmax = -amax / (2.0 * j) - (v_amax - vmax) / amax;
        b.t[1] = hold_to_vmin.min((hold_to_vmax - EPS).max(0.0));
    }
    b
}

/// Braking pre-trajectory for the position interface (symmetric limits).
pub(crate) fn position_brake(v0: f64, a0: f64, vm: f64, am: f64, jm: f64) -> Brake {
    let vaz = |v: f64, a: f64, j: f64| v + a * a / (2.0 * j);
    if a0 > am {
        acceleration_brake(v0, a0, vm, -vm, am, -am, jm)
    } else if a0 < -am {
        acceleration_brake(v0, a0, -vm, vm, -am, am, -jm)
    } else if (v0 > vm && vaz(v0, a0, -jm) > -vm) || (a0 > 0.0 && vaz(v0, a0, jm) > vm) {
        velocity_brake(v0, a0, vm, -vm, -am, jm)
    } else if (v0 < -vm && vaz(v0, a0, jm) < vm) || (a0 < 0.0 && vaz(v0, a0, -jm) < -vm) {
        velocity_brake(v0, a0, -vm, vm, am, -jm)
    } else {
        Brake::default()
    }
}

/// Braking pre-trajectory for the velocity interface: only the acceleration
/// limit is restored (the velocity is the controlled quantity).
pub(crate) fn velocity_interface_brake(a0: f64, am: f64, jm: f64) -> Brake {
    if a0 > am {
        Brake { t: [(a0 - am) / jm + f64::EPSILON, 0.0], j: [-jm, 0.0] }
    } else if a0 < -am {
        Brake { t: [(-am - a0) / jm + f64::EPSILON, 0.0], j: [jm, 0.0] }
    } else {
        Brake::default()
    }
}

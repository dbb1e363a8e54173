//! Input validation, per-joint minimum durations and synchronization of all
//! joints to a common duration.

use crate::brake::{position_brake, velocity_interface_brake, Brake};
use crate::profile::{accel_tol, integrate, Profile};
use crate::step1::{Problem, Step1};
use crate::{step2, velocity, KinState, Limits, Options, OtgError, Sync, Trajectory};

/// Relative tolerance for reaching a target state when verifying profiles.
pub(crate) const REACH_TOL: f64 = 5e-10;

pub(crate) fn validate_limits<const N: usize>(l: &Limits<N>) -> Result<(), OtgError> {
    for j in 0..N {
        for (which, value) in [("v_max", l.v_max[j]), ("a_max", l.a_max[j]), ("j_max", l.j_max[j])] {
            if !(value.is_finite() && value > 0.0) {
                return Err(OtgError::InvalidLimit { joint: j, which, value });
            }
        }
    }
    Ok(())
}

pub(crate) fn validate_state<const N: usize>(
    s: &KinState<N>,
    prefix: &'static [&'static str; 3],
) -> Result<(), OtgError> {
    for j in 0..N {
        for (which, value) in [(prefix[0], s.p[j]), (prefix[1], s.v[j]), (prefix[2], s.a[j])] {
            if !value.is_finite() {
                return Err(OtgError::NonFiniteState { joint: j, which, value });
            }
        }
    }
    Ok(())
}

pub(crate) fn validate_options<const N: usize>(o: &Options<N>) -> Result<(), OtgError> {
    if let Some(d) = o.min_duration {
        if !(d.is_finite() && d >= 0.0) {
            return Err(OtgError::InvalidOption { which: "min_duration", value: d });
        }
    }
    if let Some(p) = o.period {
        if !(p.is_finite() && p > 0.0) {
            return Err(OtgError::InvalidOption { which: "period", value: p });
        }
    }
    Ok(())
}

/// Target velocity/acceleration validity for one joint (shared by both interfaces).
pub(crate) fn validate_target_va(
    j: usize,
    vf: f64,
    af: f64,
    vm: f64,
    am: f64,
    jm: f64,
) -> Result<(), OtgError> {
    if vf.abs() > vm {
        return Err(OtgError::TargetVelocityBeyondLimit { joint: j, value: vf, limit: vm });
    }
    if af.abs() > am {
        return Err(OtgError::TargetAccelerationBeyondLimit { joint: j, value: af, limit: am });
    }
    if (af < 0.0 && vf + af * af / (2.0 * jm) > vm) || (af > 0.0 && vf - af * af / (2.0 * jm) < -vm) {
        return Err(OtgError::UnreachableTargetAcceleration { joint: j, velocity: vf, acceleration: af });
    }
    Ok(())
}

pub(crate) const CUR: [&str; 3] = ["current position", "current velocity", "current acceleration"];
pub(crate) const TGT: [&str; 3] = ["target position", "target velocity", "target acceleration"];

/// Apply minimum duration and period rounding to a duration.
pub(crate) fn adjust_duration<const N: usize>(t: f64, o: &Options<N>) -> f64 {
    let mut t = t;
    if let Some(m) = o.min_duration {
        t = t.max(m);
    }
    if let Some(p) = o.period {
        let k = (t / p - 1e-9).ceil().max(0.0);
        t = k * p;
    }
    t
}

/// Start a profile with its braking phases; returns the profile and the post-brake state.
fn start_with_brake(p0: f64, v0: f64, a0: f64, b: &Brake) -> (Profile, (f64, f64, f64)) {
    let mut pr = Profile::new(p0, v0, a0);
    let mut s = (p0, v0, a0);
    for i in 0..2 {
        if b.t[i] > 0.0 {
            pr.push(b.t[i], b.j[i]);
            s = integrate(b.t[i], s.0, s.1, s.2, b.j[i]);
        }
    }
    (pr, s)
}

fn hold_profile(p0: f64, v0: f64, a0: f64) -> Profile {
    Profile::new(p0, v0, a0)
}

impl<const N: usize> Trajectory<N> {
    /// Time-optimal trajectory from `current` to `target` (position interface:
    /// target position, velocity and acceleration) under `limits`.
    pub fn calculate(
        current: &KinState<N>,
        target: &KinState<N>,
        limits: &Limits<N>,
        options: &Options<N>,
    ) -> Result<Self, OtgError> {
        let mut tr = Self::hold(current);
        tr.calculate_into(current, target, limits, options)?;
        Ok(tr)
    }

    /// [`Trajectory::calculate`] into `self` (on an error `self` is left as it was): a caller
    /// computing many motions (a planner's edges) keeps one trajectory and refills it,
    /// instead of building, zeroing and moving an 18.7 kB value per motion. The same
    /// trajectory as `calculate`'s.
    pub fn calculate_into(
        &mut self,
        current: &KinState<N>,
        target: &KinState<N>,
        limits: &Limits<N>,
        options: &Options<N>,
    ) -> Result<(), OtgError> {
        validate_limits(limits)?;
        validate_state(current, &CUR)?;
        validate_state(target, &TGT)?;
        validate_options(options)?;
        for j in 0..N {
            if options.enabled[j] {
                validate_target_va(
                    j,
                    target.v[j],
                    target.a[j],
                    limits.v_max[j],
                    limits.a_max[j],
                    limits.j_max[j],
                )?;
            }
        }
        // Phase synchronization, when it applies, is the answer (below, after each joint's
        // time-optimal profile): tried first, it spares those six solves. They only decide
        // the answer when one of them fails, and a joint whose minimum duration reaches 1e12 s
        // makes the phase-synchronized duration reach it too; so a phase-synchronized
        // trajectory shorter than that is returned as found, anything else goes the whole way.
        let no_brake = || {
            (0..N).all(|j| {
                let (v, a) = (current.v[j], current.a[j]);
                !options.enabled[j]
                    || position_brake(v, a, limits.v_max[j], limits.a_max[j], limits.j_max[j]).duration()
                        == 0.0
            })
        };
        if options.sync == Sync::Phase && no_brake() {
            if let Some((profiles, finals, t)) = phase_sync(current, target, limits, options) {
                if t < 1e12 {
                    self.fill(&profiles, &finals, t);
                    return Ok(());
                }
            }
        }
        let mut profiles = [Profile::new(0.0, 0.0, 0.0); N];
        let mut finals = [[0.0; 3]; N];
        let mut brake_t = [0.0f64; N];
        let mut steps: [Option<Step1>; N] = [None; N];
        let mut problems: [Option<Problem>; N] = [None; N];
        let mut t_sync = 0.0f64;
        for j in 0..N {
            let (p0, v0, a0) = (current.p[j], current.v[j], current.a[j]);
            if !options.enabled[j] {
                profiles[j] = hold_profile(p0, v0, a0);
                finals[j] = [p0, v0, a0];
                continue;
            }
            let (vm, am, jm) = (limits.v_max[j], limits.a_max[j], limits.j_max[j]);
            let b = position_brake(v0, a0, vm, am, jm);
            let (head, s) = start_with_brake(p0, v0, a0, &b);
            profiles[j] = head;
            brake_t[j] = b.duration();
            let pb = Problem {
                p0: s.0,
                v0: s.1,
                a0: s.2,
                pf: target.p[j],
                vf: target.v[j],
                af: target.a[j],
                vm,
                am,
                jm,
            };
            let st = steps[j].insert(pb.solve().ok_or(OtgError::NoSolution { joint: j })?);
            t_sync = t_sync.max(brake_t[j] + st.t_min);
            if !(t_sync < 1e12) {
                return Err(OtgError::DurationTooLong { joint: j, duration: t_sync });
            }
            problems[j] = Some(pb);
            finals[j] = [target.p[j], target.v[j], target.a[j]];
        }
        if options.sync == Sync::Phase && brake_t.iter().all(|&b| b == 0.0) {
            if let Some((profiles, finals, t)) = phase_sync(current, target, limits, options) {
                self.fill(&profiles, &finals, t);
                return Ok(());
            }
        }
        if options.sync == Sync::None {
            for j in 0..N {
                if let Some(st) = &steps[j] {
                    profiles[j].extend(&st.best);
                }
            }
            let t = adjust_duration(t_sync, options);
            self.fill(&profiles, &finals, t);
            return Ok(());
        }
        // Earliest duration >= every minimum, not blocked for any joint.
        let mut t_sync = adjust_duration(t_sync, options);
        for _ in 0..4 * N + 4 {
            let mut moved = false;
            for j in 0..N {
                if let Some(st) = &steps[j] {
                    let tt = t_sync - brake_t[j];
                    for &(l, r) in &st.blocked[..st.n_blocked] {
                        if tt > l && tt < r {
                            t_sync = adjust_duration(r + brake_t[j], options);
                            moved = true;
                        }
                    }
                }
            }
            if !moved {
                break;
            }
        }
        for j in 0..N {
            let (Some(st), Some(pb)) = (&steps[j], &problems[j]) else { continue };
            let tt = t_sync - brake_t[j];
            let close = |x: f64| (tt - x).abs() <= 1e-12 * (1.0 + t_sync);
            // The heads (braking phases) are already in `profiles`.
            if close(st.t_min) {
                profiles[j].extend(&st.best);
            } else if let Some(k) = (0..st.n_blocked).find(|&k| close(st.blocked[k].1)) {
                profiles[j].extend(&st.right[k]);
            } else {
                let main = step2::with_duration(pb, tt).ok_or(OtgError::NoSolution { joint: j })?;
                profiles[j].extend(&main);
            }
        }
        for j in 0..N {
            if options.enabled[j] {
                verify(&profiles[j], &finals[j], j)?;
            }
        }
        self.fill(&profiles, &finals, t_sync);
        Ok(())
    }

    /// Time-optimal trajectory that reaches `target_v`/`target_a` (velocity
    /// interface; positions are free) under `limits`. With zero targets this is
    /// the fastest jerk-limited brake to rest. A current acceleration beyond the
    /// limit is first ramped back inside it.
    pub fn calculate_velocity(
        current: &KinState<N>,
        target_v: &[f64; N],
        target_a: &[f64; N],
        limits: &Limits<N>,
        options: &Options<N>,
    ) -> Result<Self, OtgError> {
        validate_limits(limits)?;
        validate_state(current, &CUR)?;
        validate_state(&KinState { p: [0.0; N], v: *target_v, a: *target_a }, &TGT)?;
        validate_options(options)?;
        for j in 0..N {
            if options.enabled[j] {
                let (vm, am, jm) = (limits.v_max[j], limits.a_max[j], limits.j_max[j]);
                validate_target_va(j, target_v[j], target_a[j], vm, am, jm)?;
            }
        }
        let mut profiles = [Profile::new(0.0, 0.0, 0.0); N];
        let mut finals = [[0.0; 3]; N];
        let mut tmin = [0.0f64; N];
        let mut t_sync = 0.0f64;
        for j in 0..N {
            let (p0, v0, a0) = (current.p[j], current.v[j], current.a[j]);
            if !options.enabled[j] {
                profiles[j] = hold_profile(p0, v0, a0);
                finals[j] = [p0, v0, a0];
                continue;
            }
            let (am, jm) = (limits.a_max[j], limits.j_max[j]);
            let b = velocity_interface_brake(a0, am, jm);
            let (mut pr, s) = start_with_brake(p0, v0, a0, &b);
            let a_s = s.2.clamp(-am, am);
            let vp = velocity::min_time(s.1, a_s, target_v[j], target_a[j], am, jm)
                .ok_or(OtgError::NoSolution { joint: j })?;
            for i in 0..3 {
                pr.push(vp.t[i], vp.j[i]);
            }
            tmin[j] = pr.duration();
            profiles[j] = pr;
            t_sync = t_sync.max(tmin[j]);
        }
        let mut t_sync = adjust_duration(t_sync, options);
        // A joint may have a blocked duration interval: move the common
        // duration past it and start over (a few rounds at most).
        let mut mains = [velocity::VelProfile::default(); N];
        if options.sync != Sync::None {
            'rounds: for _ in 0..2 * N + 2 {
                for j in 0..N {
                    if !options.enabled[j] || tmin[j] == t_sync {
                        continue;
                    }
                    let (am, jm) = (limits.a_max[j], limits.j_max[j]);
                    let b = velocity_interface_brake(current.a[j], am, jm);
                    let (_, s) = start_with_brake(current.p[j], current.v[j], current.a[j], &b);
                    let a_s = s.2.clamp(-am, am);
                    let tt = t_sync - b.duration();
                    let (t_ok, vp) = velocity::next_feasible(s.1, a_s, target_v[j], target_a[j], am, jm, tt)
                        .ok_or(OtgError::NoSolution { joint: j })?;
                    if t_ok > tt {
                        t_sync = adjust_duration(t_ok + b.duration(), options);
                        continue 'rounds;
                    }
                    mains[j] = vp;
                }
                break;
            }
        }
        for j in 0..N {
            if !options.enabled[j] {
                continue;
            }
            let (p0, v0, a0) = (current.p[j], current.v[j], current.a[j]);
            let (am, jm) = (limits.a_max[j], limits.j_max[j]);
            if options.sync != Sync::None && tmin[j] != t_sync {
                let b = velocity_interface_brake(a0, am, jm);
                let (mut pr, _) = start_with_brake(p0, v0, a0, &b);
                let vp = mains[j];
                for i in 0..3 {
                    pr.push(vp.t[i], vp.j[i]);
                }
                profiles[j] = pr;
            }
            let (pe, _, _) = profiles[j].end_state();
            finals[j] = [pe, target_v[j], target_a[j]];
            let (_, ve, ae) = profiles[j].end_state();
            if (ve - target_v[j]).abs() > 1e-9 * (1.0 + target_v[j].abs()) || (ae - target_a[j]).abs() > 1e-9
            {
                return Err(OtgError::NoSolution { joint: j });
            }
        }
        Ok(Self::from_profiles(&profiles, &finals, t_sync))
    }
}

/// Check by forward integration that a profile reaches its target.
pub(crate) fn verify(pr: &Profile, fin: &[f64; 3], joint: usize) -> Result<(), OtgError> {
    let (p, v, a) = pr.end_state();
    let ok = (p - fin[0]).abs() <= REACH_TOL * (1.0 + fin[0].abs())
        && (v - fin[1]).abs() <= REACH_TOL * (1.0 + fin[1].abs())
        && (a - fin[2]).abs() <= accel_tol(fin[2], pr.accel_swing());
    if ok {
        Ok(())
    } else {
        Err(OtgError::NoSolution { joint })
    }
}

/// Phase synchronization: if every enabled joint's start and target state
/// are the same multiple `λ_j` of one reference joint's (largest move), all
/// joints follow the reference profile scaled by `λ_j` — a straight line in
/// joint space. The reference is solved under the tightest scaled limits
/// `min_j limit_j/|λ_j|`. Returns the joints' profiles, their final states and the
/// duration ([`Trajectory::fill`]'s input); `None` when the states are not collinear.
fn phase_sync<const N: usize>(
    current: &KinState<N>,
    target: &KinState<N>,
    limits: &Limits<N>,
    options: &Options<N>,
) -> Option<([Profile; N], [[f64; 3]; N], f64)> {
    let k = (0..N)
        .filter(|&j| options.enabled[j])
        .max_by(|&a, &b| (target.p[a] - current.p[a]).abs().total_cmp(&(target.p[b] - current.p[b]).abs()))?;
    let dk = target.p[k] - current.p[k];
    if dk == 0.0 {
        return None;
    }
    let (mut vr, mut ar, mut jr) = (f64::INFINITY, f64::INFINITY, f64::INFINITY);
    let mut lam = [0.0; N];
    for j in 0..N {
        if !options.enabled[j] {
            continue;
        }
        let l = (target.p[j] - current.p[j]) / dk;
        lam[j] = l;
        let close = |x: f64, y: f64| (x - l * y).abs() <= 1e-12 * (1.0 + x.abs());
        if !(close(current.v[j], current.v[k])
            && close(current.a[j], current.a[k])
            && close(target.v[j], target.v[k])
            && close(target.a[j], target.a[k]))
        {
            return None;
        }
        if l != 0.0 {
            vr = vr.min(limits.v_max[j] / l.abs());
            ar = ar.min(limits.a_max[j] / l.abs());
            jr = jr.min(limits.j_max[j] / l.abs());
        }
    }
    let pb = Problem {
        p0: current.p[k],
        v0: current.v[k],
        a0: current.a[k],
        pf: target.p[k],
        vf: target.v[k],
        af: target.a[k],
        vm: vr,
        am: ar,
        jm: jr,
    };
    // On the line the reference moves under the scaled limits; if those need a brake (a
    // joint whose own jerk would keep it within its velocity limit may not, at the line's
    // lower jerk), no line stays within every joint's limits: time sync.
    if validate_target_va(k, pb.vf, pb.af, vr, ar, jr).is_err()
        || current.v[k].abs() > vr
        || current.a[k].abs() > ar
        || position_brake(pb.v0, pb.a0, vr, ar, jr).duration() > 0.0
    {
        return None;
    }
    let st = pb.solve()?;
    let t = adjust_duration(st.t_min, options);
    let main = if t == st.t_min { st.best } else { step2::with_duration(&pb, t)? };
    let mut profiles = [Profile::new(0.0, 0.0, 0.0); N];
    let mut finals = [[0.0; 3]; N];
    for j in 0..N {
        if !options.enabled[j] {
            profiles[j] = hold_profile(current.p[j], current.v[j], current.a[j]);
            finals[j] = [current.p[j], current.v[j], current.a[j]];
            continue;
        }
        let mut pr = Profile::new(current.p[j], current.v[j], current.a[j]);
        for i in 0..main.n {
            pr.push(main.t[i], main.j[i] * lam[j]);
        }
        finals[j] = [target.p[j], target.v[j], target.a[j]];
        verify(&pr, &finals[j], j).ok()?;
        profiles[j] = pr;
    }
    Some((profiles, finals, main.duration().max(t)))
}

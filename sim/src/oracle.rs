//! The true future of the debris, for the `oracle-rrt` method (an upper bound on what any
//! predictor can give the planner; in process only, since no real system has it).
//!
//! [`TruthTable::record`] steps a copy of the simulator's debris world with the very same
//! period as the simulator (so the copy's states, scheduled impulses and splits included, are
//! the states the simulator will reach) and keeps every object's pose every
//! `sample_ticks` ticks. [`TruthTable::forecast_into`] writes a [`DebrisForecast`] from it:
//! the true poses at `t0 + k·dt` (linear position, slerp attitude between kept samples), with
//! zero uncertainty, in the arm's base frame, with the same shape descriptors the
//! observations carry.

use dkrrt_collision::{descriptor_of, interpolate_pose};
use dkrrt_debris::DebrisWorld;
use dkrrt_msg::{DebrisForecast, DebrisShape, ForecastStep, FORECAST_STEPS, MAX_DEBRIS};

/// One kept sample: up to [`MAX_DEBRIS`] objects (id, LVLH pose `[p, q]`).
#[derive(Debug, Clone, Copy)]
struct Sample {
    count: usize,
    ids: [u32; MAX_DEBRIS],
    poses: [[f64; 7]; MAX_DEBRIS],
}

/// The recorded true future of a debris world.
#[derive(Debug, Clone)]
pub struct TruthTable {
    /// Seconds between kept samples.
    sample_s: f64,
    samples: Vec<Sample>,
    /// Shape descriptor and bounding radius per id (every object seen, fragments included).
    shapes: Vec<(u32, DebrisShape, f64)>,
    base: [f64; 3],
}

impl TruthTable {
    /// Steps a copy of `world` `ticks` times by `dt` (as the simulator does) and keeps the
    /// poses every `sample_ticks` ticks (and at the start). `base` is the arm base in LVLH.
    /// Allocates: start-up only.
    pub fn record(world: &DebrisWorld, dt: f64, ticks: u64, sample_ticks: u64, base: [f64; 3]) -> TruthTable {
        let sample_ticks = sample_ticks.max(1);
        let mut w = world.clone();
        let mut table = TruthTable {
            sample_s: dt * sample_ticks as f64,
            samples: Vec::with_capacity((ticks / sample_ticks + 2) as usize),
            shapes: Vec::new(),
            base,
        };
        table.keep(&w);
        for tick in 1..=ticks {
            w.step(dt);
            if tick % sample_ticks == 0 {
                table.keep(&w);
            }
        }
        table
    }

    fn keep(&mut self, w: &DebrisWorld) {
        let mut s = Sample { count: 0, ids: [0; MAX_DEBRIS], poses: [[0.0; 7]; MAX_DEBRIS] };
        for d in w.debris().iter().take(MAX_DEBRIS) {
            let (p, q) = (&d.state.p, d.state.q.quaternion());
            s.ids[s.count] = d.id;
            s.poses[s.count] = [p.x, p.y, p.z, q.w, q.i, q.j, q.k];
            s.count += 1;
            if !self.shapes.iter().any(|e| e.0 == d.id) {
                self.shapes.push((d.id, descriptor_of(d.props.shape.as_ref()), d.props.bounding_radius));
            }
        }
        self.samples.push(s);
    }

    /// Seconds of truth recorded.
    pub fn span_s(&self) -> f64 {
        self.samples.len().saturating_sub(1) as f64 * self.sample_s
    }

    /// The true LVLH pose of `id` at time `t` (s from the recording's start); before the
    /// object exists (a fragment not yet split off) its first pose, after it is gone or past
    /// the end of the recording its last one. `None` for an id never seen.
    pub fn pose(&self, id: u32, t: f64) -> Option<([f64; 3], [f64; 4])> {
        let last = self.samples.len().checked_sub(1)?;
        let x = (t / self.sample_s).clamp(0.0, last as f64);
        let i = (x.floor() as usize).min(last.saturating_sub(1));
        let f = if last == 0 { 0.0 } else { x - i as f64 };
        let get = |s: &Sample| s.ids[..s.count].iter().position(|&j| j == id).map(|k| s.poses[k]);
        let (a, b) = match (get(&self.samples[i]), get(&self.samples[(i + 1).min(last)])) {
            (Some(a), Some(b)) => (a, b),
            (Some(a), None) => (a, a),
            (None, Some(b)) => (b, b),
            (None, None) => {
                let a = self.samples[i..]
                    .iter()
                    .find_map(get)
                    .or_else(|| self.samples[..i].iter().rev().find_map(get))?;
                (a, a)
            }
        };
        Some(interpolate_pose(
            &[a[0], a[1], a[2]],
            &[a[3], a[4], a[5], a[6]],
            &[b[0], b[1], b[2]],
            &[b[3], b[4], b[5], b[6]],
            f,
        ))
    }

    /// Ids existing at time `t` (the nearest sample).
    fn ids_at(&self, t: f64) -> &[u32] {
        let last = self.samples.len().saturating_sub(1);
        let s = &self.samples[((t / self.sample_s).round().max(0.0) as usize).min(last)];
        &s.ids[..s.count]
    }

    /// Writes the true future from `t0` (s): `steps` steps of `dt` for every object that
    /// exists at `t0`, zero uncertainty, base frame. Returns the number of tracks written.
    /// Allocation-free.
    pub fn forecast_into(&self, t0: f64, steps: usize, dt: f64, msg: &mut DebrisForecast) -> usize {
        let steps = steps.clamp(1, FORECAST_STEPS);
        if self.samples.is_empty() {
            return 0;
        }
        let b = self.base;
        // Every object that exists now or by the end of the horizon (a fragment that will
        // split off is known to the oracle from its first pose).
        let (now, end) = (self.ids_at(t0), self.ids_at(t0 + steps as f64 * dt));
        let mut n = 0;
        for (j, &id) in now.iter().chain(end.iter()).enumerate() {
            if n == MAX_DEBRIS || (j >= now.len() && now.contains(&id)) {
                continue;
            }
            let Some(&(_, shape, radius)) = self.shapes.iter().find(|e| e.0 == id) else { continue };
            let tr = &mut msg.tracks[n];
            tr.id = id;
            tr.bounding_radius = radius;
            tr.shape = shape;
            for k in 1..=steps {
                let Some((p, q)) = self.pose(id, t0 + k as f64 * dt) else { continue };
                tr.steps[k - 1] = ForecastStep {
                    p: [p[0] - b[0], p[1] - b[1], p[2] - b[2]],
                    q,
                    sigma_m: 0.0,
                    sigma_pos_m: 0.0,
                };
            }
            n += 1;
        }
        msg.count = n as u32;
        msg.steps = steps as u32;
        msg.dt_s = dt;
        msg.t0_ns = (t0.max(0.0) * 1e9).round() as u64;
        msg.header.stamp_ns = msg.t0_ns;
        msg.header.flags = 0;
        n
    }
}

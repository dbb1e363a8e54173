//! Training from recorded observations (a real sensor's, or the simulator's): the file
//! format `dkrrt record` writes, and the attitude trajectories the deep model is trained on.
//!
//! **Format** (JSON lines, one observation item per line, in arrival order):
//! `{"t": 12.34, "id": 3, "p": [x, y, z], "q": [w, x, y, z]}` with the measurement time `t`
//! [s], the debris id, the position [m] and the attitude body → frame (unit quaternion, any
//! sign); optionally `"v": [..], "w": [..]` (velocity [m/s], body rate [rad/s]) when the
//! sensor reports rates; optionally `"flags": n`, the `DebrisObs` flags a perception front end
//! set (bit 1 `DEBRIS_PARTIAL`, bit 2 `DEBRIS_RESTART`, bit 3 `DEBRIS_AXIS_ONLY`; written when
//! any is set, other bits are an error). Positions are in the arm base frame, whose axes are those of the
//! module's LVLH frame (the attitude model needs only the attitude). Blank lines are skipped;
//! anything else that is not such an item is an error naming the line.
//!
//! **Trajectories**: every object is tracked by the predictor's own gate and pose filter (the
//! scenario's noise, constant-velocity models); the filtered `(q, ω)` is sampled on the model
//! grid `k·dt` by propagating the estimate of the last accepted observation
//! ([`crate::filter::propagate`]). A gap longer than `max_gap` between accepted observations
//! (dropouts, or observations the gate rejected) or a re-initialised track ends a trajectory;
//! the first `warmup` seconds of each are skipped (filter convergence).

use crate::filter::propagate;
use crate::predictor::{DebrisPredictor, PredictorConfig};
use crate::training::{validate, TrainOptions, TrainedModels, ValidationRow};
use crate::Models;
use dkrrt_debris::Observation;
use dkrrt_deep::{Progress, TrainData};
use dkrrt_koopman::debris_state::align_quaternion;
use dkrrt_msg::{DEBRIS_AXIS_ONLY, DEBRIS_PARTIAL, DEBRIS_RESTART};
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::io::{BufRead, Write};

/// One line of the file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Line {
    t: f64,
    id: u32,
    p: [f64; 3],
    q: [f64; 4],
    #[serde(default, skip_serializing_if = "Option::is_none")]
    v: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    w: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "is_zero")]
    flags: u32,
}

fn is_zero(v: &u32) -> bool {
    *v == 0
}

/// The flags a line may carry (module docs).
const LINE_FLAGS: u32 = DEBRIS_PARTIAL | DEBRIS_RESTART | DEBRIS_AXIS_ONLY;

/// Writes `o` as one line of the format.
pub fn write_observation(out: &mut impl Write, o: &Observation) -> std::io::Result<()> {
    let line = Line {
        t: o.t,
        id: o.id,
        p: o.p,
        q: o.q,
        v: o.has_rates.then_some(o.v),
        w: o.has_rates.then_some(o.w),
        flags: [(o.partial, DEBRIS_PARTIAL), (o.restart, DEBRIS_RESTART), (o.axis_only, DEBRIS_AXIS_ONLY)]
            .iter()
            .filter(|(on, _)| *on)
            .fold(0, |f, (_, bit)| f | bit),
    };
    serde_json::to_writer(&mut *out, &line).map_err(std::io::Error::other)?;
    out.write_all(b"\n")
}

/// Reads a file of the format; `origin` names it in errors (`origin:LINE: …`). Non-finite
/// numbers, a zero quaternion or only one of `v` / `w` are errors.
pub fn read_observations(input: impl BufRead, origin: &str) -> Result<Vec<Observation>, String> {
    let mut out = Vec::new();
    for (i, line) in input.lines().enumerate() {
        let line = line.map_err(|e| format!("{origin}:{}: {e}", i + 1))?;
        if line.trim().is_empty() {
            continue;
        }
        let l: Line = serde_json::from_str(&line).map_err(|e| format!("{origin}:{}: {e}", i + 1))?;
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        let rates_ok = l.v.is_some() == l.w.is_some();
        let (v, w) = (l.v.unwrap_or_default(), l.w.unwrap_or_default());
        let qn = l.q.iter().map(|x| x * x).sum::<f64>().sqrt();
        if !(l.t.is_finite() && finite(&l.p) && finite(&l.q) && finite(&v) && finite(&w)) {
            return Err(format!("{origin}:{}: non-finite number", i + 1));
        }
        if !(qn > 0.5 && qn < 1.5) {
            return Err(format!("{origin}:{}: q is not a unit quaternion (norm {qn})", i + 1));
        }
        if !rates_ok {
            return Err(format!("{origin}:{}: \"v\" and \"w\" go together", i + 1));
        }
        if l.flags & !LINE_FLAGS != 0 {
            return Err(format!(
                "{origin}:{}: flags {}: only bits 1-3 (partial, restart, axis only)",
                i + 1,
                l.flags
            ));
        }
        out.push(Observation {
            id: l.id,
            t: l.t,
            t_avail: l.t,
            p: l.p,
            q: l.q.map(|x| x / qn),
            v,
            w,
            has_rates: l.v.is_some(),
            partial: l.flags & DEBRIS_PARTIAL != 0,
            restart: l.flags & DEBRIS_RESTART != 0,
            axis_only: l.flags & DEBRIS_AXIS_ONLY != 0,
            seq: i as u32,
        });
    }
    Ok(out)
}

/// One object's filtered attitude on the model grid.
#[derive(Debug, Clone, PartialEq)]
pub struct AttitudeTrack {
    /// Debris id.
    pub id: u32,
    /// Time of the first sample [s] (a multiple of `dt`).
    pub t0: f64,
    /// `[q(4), ω(3)]` per grid step, quaternions sign-continuous.
    pub x: Vec<f64>,
}

/// Filtered attitude trajectories (see the module doc) from observations in arrival order;
/// `frame_rate` is the orbit's mean motion [rad/s]. Trajectories shorter than 2 steps are
/// dropped; sorted by id, then time.
pub fn attitude_trajectories(
    obs: &[Observation],
    frame_rate: f64,
    dt: f64,
    cfg: &PredictorConfig,
    warmup: f64,
    max_gap: f64,
) -> Vec<AttitudeTrack> {
    let models = Models::constant_velocity(dt, 1, frame_rate, 0.0, 0.0);
    let mut pcfg = *cfg;
    pcfg.filter.frame_rate = frame_rate;
    let mut pred = DebrisPredictor::new(models, pcfg);
    // Per id: (time of the track's first accepted observation, trajectory being built).
    let mut open: HashMap<u32, (f64, AttitudeTrack)> = HashMap::new();
    let mut done: Vec<AttitudeTrack> = Vec::new();
    let new_track = |id: u32| AttitudeTrack { id, t0: f64::NAN, x: Vec::new() };
    for o in obs {
        let before = pred.track(o.id).map(|t| (t.t, t.state, t.n_obs));
        pred.observe(o);
        let Some(now) = pred.track(o.id) else { continue };
        if now.t != o.t {
            continue; // rejected by the gate
        }
        let continues = matches!(before, Some((t0, _, n)) if o.t - t0 <= max_gap && now.n_obs == n + 1);
        if !continues {
            if let Some((_, tr)) = open.remove(&o.id) {
                done.push(tr);
            }
            open.insert(o.id, (o.t, new_track(o.id)));
            continue;
        }
        let (t_prev, x_prev, _) = before.unwrap();
        let (t_first, track) = open.entry(o.id).or_insert_with(|| (t_prev, new_track(o.id)));
        // Grid times in (t_prev, o.t], from the previous estimate.
        let mut g = (t_prev / dt).floor() as i64 + 1;
        while g as f64 * dt <= t_prev + 1e-9 {
            g += 1; // `t_prev` on the grid, up to rounding: it was sampled already
        }
        while g as f64 * dt <= o.t + 1e-9 {
            let tg = g as f64 * dt;
            g += 1;
            if tg - *t_first < warmup {
                continue;
            }
            let x = propagate(&x_prev, frame_rate, tg - t_prev);
            let mut s = [x[6], x[7], x[8], x[9], x[10], x[11], x[12]];
            if track.x.is_empty() {
                track.t0 = tg;
            }
            let tr = &mut track.x;
            if tr.len() >= 7 {
                let prev = [tr[tr.len() - 7], tr[tr.len() - 6], tr[tr.len() - 5], tr[tr.len() - 4]];
                align_quaternion(&mut s[..4], &prev);
            }
            tr.extend_from_slice(&s);
        }
    }
    done.extend(open.into_values().map(|(_, t)| t));
    done.retain(|t| t.x.len() >= 14);
    done.sort_by(|a, b| (a.id, a.t0).partial_cmp(&(b.id, b.t0)).unwrap_or(std::cmp::Ordering::Equal));
    done
}

/// Trains the deep attitude model on recorded observations: trajectories as in
/// [`attitude_trajectories`] (warm-up 1 s, gaps ≤ 0.5 s), the first three quarters of each
/// for training and the last quarter (later in time, held out) for validation, which needs
/// at least the longest validation horizon. Network and optimiser: `opts.deep`, grid `opts.dt`.
pub fn train_from_observations(
    recordings: &[Vec<Observation>],
    frame_rate: f64,
    cfg: &PredictorConfig,
    opts: &TrainOptions,
    progress: &mut dyn FnMut(&Progress),
) -> Result<TrainedModels, String> {
    let hmax = opts.valid_horizons.iter().fold(0.0f64, |a, &h| a.max(h));
    let hsteps = (hmax / opts.dt).round() as usize;
    let mut train = TrainData { n: 7, dt: opts.dt, trajectories: Vec::new() };
    let mut valid = TrainData { n: 7, dt: opts.dt, trajectories: Vec::new() };
    for obs in recordings {
        for AttitudeTrack { x: tr, .. } in attitude_trajectories(obs, frame_rate, opts.dt, cfg, 1.0, 0.5) {
            let steps = tr.len() / 7;
            let cut = steps * 3 / 4;
            if steps - cut > hsteps {
                valid.trajectories.push(tr[cut * 7..].to_vec());
                train.trajectories.push(tr[..cut * 7].to_vec());
            } else {
                train.trajectories.push(tr);
            }
        }
    }
    let min = opts.deep.horizon + 1;
    train.trajectories.retain(|t| t.len() / 7 >= min);
    if train.trajectories.is_empty() {
        return Err(format!(
            "recorded observations: no object was tracked for {} s without a gap (the training \
             horizon plus 1 s of filter warm-up)",
            (min as f64 * opts.dt + 1.0)
        ));
    }
    let (attitude, report) = dkrrt_deep::train(&train, &opts.deep, progress).map_err(|e| e.to_string())?;
    let validation: Vec<ValidationRow> = if valid.trajectories.is_empty() {
        Vec::new()
    } else {
        validate(&attitude, &valid, &opts.valid_horizons, 5)
    };
    Ok(TrainedModels { attitude, report: Some(report), validation })
}

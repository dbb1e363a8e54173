//! Validation of incoming payloads. Every consumer validates each message
//! before use; a rejected message is counted and dropped, never half-used.

use crate::types::*;

/// Why a payload was rejected. `field` names the offending field.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum ValidationError {
    #[error("{field}[{index}] is not finite")]
    NonFinite { field: &'static str, index: usize },
    #[error("{field}[{index}] = {value} is outside [{min}, {max}]")]
    OutOfRange { field: &'static str, index: usize, value: f64, min: f64, max: f64 },
    #[error("{field} = {value} exceeds the capacity {max}")]
    Count { field: &'static str, value: u64, max: u64 },
    #[error("{field} = {value} is not a known value")]
    BadEnum { field: &'static str, value: u32 },
    #[error("{field}[{index}] has norm {norm}, expected a unit quaternion")]
    NotUnit { field: &'static str, index: usize, norm: f64 },
    #[error("{field}[{index}] breaks the required order (segment times must start at 0 and increase)")]
    Order { field: &'static str, index: usize },
}

/// The physical limits messages are checked against (from the arm model and
/// the scenario). Joint-space values of a message may exceed the limits by a
/// margin (measurements overshoot a little); beyond it the message is rejected.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContractLimits {
    pub q_min: [f64; NJ],
    pub q_max: [f64; NJ],
    pub v_max: [f64; NJ],
    pub tau_max: [f64; NJ],
    /// Extra position range allowed beyond `q_min`/`q_max`, rad.
    pub q_margin: f64,
    /// Velocity may reach `v_max · v_factor`.
    pub v_factor: f64,
    /// Debris positions must lie within this distance of the base, m.
    pub debris_range_m: f64,
    /// Debris speeds must stay below this, m/s.
    pub debris_speed_max: f64,
    /// Debris angular speeds must stay below this, rad/s.
    pub debris_spin_max: f64,
}

impl ContractLimits {
    /// Symmetric limits, handy in tests.
    pub fn symmetric(q: f64, v: f64, tau: f64) -> Self {
        ContractLimits {
            q_min: [-q; NJ],
            q_max: [q; NJ],
            v_max: [v; NJ],
            tau_max: [tau; NJ],
            q_margin: 0.05,
            v_factor: 1.5,
            debris_range_m: 1000.0,
            debris_speed_max: 100.0,
            debris_spin_max: 50.0,
        }
    }
}

fn finite(field: &'static str, xs: &[f64]) -> Result<(), ValidationError> {
    match xs.iter().position(|x| !x.is_finite()) {
        Some(index) => Err(ValidationError::NonFinite { field, index }),
        None => Ok(()),
    }
}

fn range(field: &'static str, xs: &[f64], min: &[f64], max: &[f64]) -> Result<(), ValidationError> {
    finite(field, xs)?;
    for (index, ((&value, &lo), &hi)) in xs.iter().zip(min).zip(max).enumerate() {
        if !(lo..=hi).contains(&value) {
            return Err(ValidationError::OutOfRange { field, index, value, min: lo, max: hi });
        }
    }
    Ok(())
}

fn sym(field: &'static str, xs: &[f64], bound: &[f64; NJ], factor: f64) -> Result<(), ValidationError> {
    let mut lo = [0.0; NJ];
    let mut hi = [0.0; NJ];
    for i in 0..NJ {
        hi[i] = bound[i] * factor;
        lo[i] = -hi[i];
    }
    range(field, xs, &lo, &hi)
}

fn scalar(field: &'static str, value: f64, min: f64, max: f64) -> Result<(), ValidationError> {
    range(field, &[value], &[min], &[max])
}

fn unit_quat(field: &'static str, index: usize, q: &[f64; 4]) -> Result<(), ValidationError> {
    finite(field, q)?;
    let norm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    if (norm - 1.0).abs() > 1e-3 {
        return Err(ValidationError::NotUnit { field, index, norm });
    }
    Ok(())
}

impl ContractLimits {
    fn q_bounds(&self) -> ([f64; NJ], [f64; NJ]) {
        let mut lo = self.q_min;
        let mut hi = self.q_max;
        for i in 0..NJ {
            lo[i] -= self.q_margin;
            hi[i] += self.q_margin;
        }
        (lo, hi)
    }
}

/// A payload that can check itself against the contract limits.
pub trait Validate {
    fn validate(&self, lim: &ContractLimits) -> Result<(), ValidationError>;
}

impl Validate for RobotState {
    fn validate(&self, lim: &ContractLimits) -> Result<(), ValidationError> {
        let (lo, hi) = lim.q_bounds();
        range("q", &self.q, &lo, &hi)?;
        sym("qd", &self.qd, &lim.v_max, lim.v_factor)?;
        sym("tau", &self.tau, &lim.tau_max, 1.0 + 1e-9)
    }
}

impl Validate for TorqueCommand {
    fn validate(&self, lim: &ContractLimits) -> Result<(), ValidationError> {
        // Torques beyond the limit are a controller bug, not a saturation case:
        // the plant saturates, but a command far outside is rejected.
        sym("tau", &self.tau, &lim.tau_max, 1.0 + 1e-9)?;
        let (lo, hi) = lim.q_bounds();
        range("q_set", &self.q_set, &lo, &hi)?;
        sym("qd_set", &self.qd_set, &lim.v_max, lim.v_factor)?;
        if ControllerMode::from_u32(self.mode).is_none() {
            return Err(ValidationError::BadEnum { field: "mode", value: self.mode });
        }
        Ok(())
    }
}

impl Validate for Goal {
    fn validate(&self, lim: &ContractLimits) -> Result<(), ValidationError> {
        match GoalKind::from_u32(self.kind) {
            Some(GoalKind::Joint) => range("q", &self.q, &lim.q_min, &lim.q_max),
            Some(GoalKind::Pose) => {
                for (i, v) in self.pose_p.iter().enumerate() {
                    if !v.is_finite() || v.abs() > 50.0 {
                        return Err(ValidationError::OutOfRange {
                            field: "pose_p",
                            index: i,
                            value: *v,
                            min: -50.0,
                            max: 50.0,
                        });
                    }
                }
                unit_quat("pose_q", 0, &self.pose_q)
            }
            None => Err(ValidationError::BadEnum { field: "kind", value: self.kind }),
        }
    }
}

impl Validate for Heartbeat {
    fn validate(&self, _lim: &ContractLimits) -> Result<(), ValidationError> {
        if ProcessState::from_u32(self.state).is_none() {
            return Err(ValidationError::BadEnum { field: "state", value: self.state });
        }
        if Source::from_u32(self.header.source).is_none() {
            return Err(ValidationError::BadEnum { field: "header.source", value: self.header.source });
        }
        Ok(())
    }
}

impl Validate for Trajectory {
    fn validate(&self, lim: &ContractLimits) -> Result<(), ValidationError> {
        scalar("duration_s", self.duration_s, 0.0, 24.0 * 3600.0)?;
        let (lo, hi) = lim.q_bounds();
        for j in 0..NJ {
            let n = self.n_seg[j] as usize;
            if n == 0 || n > MAX_SEGMENTS {
                return Err(ValidationError::Count {
                    field: "n_seg",
                    value: n as u64,
                    max: MAX_SEGMENTS as u64,
                });
            }
            let mut prev = -1.0;
            for (k, s) in self.seg[j][..n].iter().enumerate() {
                finite("seg", &[s.t0, s.p, s.v, s.a, s.j])
                    .map_err(|_| ValidationError::NonFinite { field: "seg", index: j * MAX_SEGMENTS + k })?;
                let first_ok = k > 0 || s.t0 == 0.0;
                if !first_ok || s.t0 <= prev && k > 0 || s.t0 > self.duration_s {
                    return Err(ValidationError::Order { field: "seg.t0", index: j * MAX_SEGMENTS + k });
                }
                prev = s.t0;
                if !(lo[j]..=hi[j]).contains(&s.p) {
                    return Err(ValidationError::OutOfRange {
                        field: "seg.p",
                        index: j * MAX_SEGMENTS + k,
                        value: s.p,
                        min: lo[j],
                        max: hi[j],
                    });
                }
                let vmax = lim.v_max[j] * lim.v_factor;
                if s.v.abs() > vmax {
                    return Err(ValidationError::OutOfRange {
                        field: "seg.v",
                        index: j * MAX_SEGMENTS + k,
                        value: s.v,
                        min: -vmax,
                        max: vmax,
                    });
                }
            }
            // The end state must also be in range.
            let end = self.sample_joint(j, self.duration_s);
            if !(lo[j]..=hi[j]).contains(&end.0) || !end.0.is_finite() {
                return Err(ValidationError::OutOfRange {
                    field: "end position",
                    index: j,
                    value: end.0,
                    min: lo[j],
                    max: hi[j],
                });
            }
        }
        Ok(())
    }
}

fn debris_pose(
    lim: &ContractLimits,
    index: usize,
    p: &[f64; 3],
    q: &[f64; 4],
    field_p: &'static str,
    field_q: &'static str,
) -> Result<(), ValidationError> {
    finite(field_p, p)?;
    let r = p.iter().map(|x| x * x).sum::<f64>().sqrt();
    if r > lim.debris_range_m {
        return Err(ValidationError::OutOfRange {
            field: field_p,
            index,
            value: r,
            min: 0.0,
            max: lim.debris_range_m,
        });
    }
    unit_quat(field_q, index, q)
}

impl DebrisShape {
    /// Checks the descriptor: a known kind, finite dimensions in (0, 50] m for the ones the kind
    /// uses, a finite offset within 50 m.
    pub fn validate(&self, field: &'static str, index: usize) -> Result<(), ValidationError> {
        let used = match ShapeKind::from_u32(self.kind) {
            None => return Err(ValidationError::BadEnum { field, value: self.kind }),
            Some(ShapeKind::Unknown) => 0,
            Some(ShapeKind::Sphere) => 1,
            Some(ShapeKind::Capsule) => 2,
            Some(ShapeKind::Box) => 3,
            Some(ShapeKind::Disc) => 2,
        };
        finite(field, &self.dims)?;
        finite(field, &self.offset)?;
        for (k, &d) in self.dims[..used].iter().enumerate() {
            if !(d > 0.0 && d <= 50.0) {
                return Err(ValidationError::OutOfRange {
                    field,
                    index: index * 3 + k,
                    value: d,
                    min: 0.0,
                    max: 50.0,
                });
            }
        }
        for (k, &o) in self.offset.iter().enumerate() {
            if o.abs() > 50.0 {
                return Err(ValidationError::OutOfRange {
                    field,
                    index: index * 3 + k,
                    value: o,
                    min: -50.0,
                    max: 50.0,
                });
            }
        }
        Ok(())
    }
}

impl DebrisObservation {
    /// Frame-level check only (`count`). Consumers that must not lose the good items of a
    /// frame with one bad item check the items one by one with [`DebrisObs::validate_item`].
    pub fn validate_frame(&self) -> Result<(), ValidationError> {
        let n = self.count as usize;
        if n > MAX_DEBRIS {
            return Err(ValidationError::Count { field: "count", value: n as u64, max: MAX_DEBRIS as u64 });
        }
        Ok(())
    }
}

impl DebrisObs {
    /// Checks one observation item (`index` is reported in the error).
    pub fn validate_item(&self, lim: &ContractLimits, index: usize) -> Result<(), ValidationError> {
        let o = self;
        let i = index;
        debris_pose(lim, i, &o.p, &o.q, "items.p", "items.q")?;
        scalar("items.bounding_radius", o.bounding_radius, 0.0, 100.0)?;
        o.shape.validate("items.shape", i)?;
        if o.flags & DEBRIS_HAS_VELOCITY != 0 {
            finite("items.v", &o.v)?;
            finite("items.w", &o.w)?;
            let s = o.v.iter().map(|x| x * x).sum::<f64>().sqrt();
            scalar("items.v", s, 0.0, lim.debris_speed_max)?;
            let w = o.w.iter().map(|x| x * x).sum::<f64>().sqrt();
            scalar("items.w", w, 0.0, lim.debris_spin_max)?;
        }
        Ok(())
    }
}

impl Validate for DebrisObservation {
    fn validate(&self, lim: &ContractLimits) -> Result<(), ValidationError> {
        self.validate_frame()?;
        for (i, o) in self.items[..self.count as usize].iter().enumerate() {
            o.validate_item(lim, i)?;
        }
        Ok(())
    }
}

impl Validate for DebrisForecast {
    fn validate(&self, lim: &ContractLimits) -> Result<(), ValidationError> {
        let n = self.count as usize;
        if n > MAX_DEBRIS {
            return Err(ValidationError::Count { field: "count", value: n as u64, max: MAX_DEBRIS as u64 });
        }
        let s = self.steps as usize;
        if s == 0 || s > FORECAST_STEPS {
            return Err(ValidationError::Count {
                field: "steps",
                value: s as u64,
                max: FORECAST_STEPS as u64,
            });
        }
        scalar("dt_s", self.dt_s, 1e-6, 10.0)?;
        for (i, t) in self.tracks[..n].iter().enumerate() {
            scalar("tracks.bounding_radius", t.bounding_radius, 0.0, 100.0)?;
            t.shape.validate("tracks.shape", i)?;
            for st in &t.steps[..s] {
                debris_pose(lim, i, &st.p, &st.q, "tracks.steps.p", "tracks.steps.q")?;
                scalar("tracks.steps.sigma_m", st.sigma_m, 0.0, lim.debris_range_m)?;
                scalar("tracks.steps.sigma_pos_m", st.sigma_pos_m, 0.0, st.sigma_m)?;
            }
        }
        Ok(())
    }
}

impl Validate for DepthImage {
    /// The image's geometry, the camera's pose and range, and every pixel's instance; a
    /// depth (mm) needs no check beyond its type (0 = no return).
    fn validate(&self, lim: &ContractLimits) -> Result<(), ValidationError> {
        let count = |field, value: usize, max: usize| {
            if value == 0 || value > max {
                Err(ValidationError::Count { field, value: value as u64, max: max as u64 })
            } else {
                Ok(())
            }
        };
        count("width", self.width as usize, DEPTH_WIDTH)?;
        count("height", self.height as usize, DEPTH_HEIGHT)?;
        let (w, h) = (self.width as f64, self.height as f64);
        scalar("focal_px", self.focal_px, 1e-3, 1e6)?;
        scalar("cx", self.cx, 0.0, w)?;
        scalar("cy", self.cy, 0.0, h)?;
        let r = lim.debris_range_m;
        range("position_m", &self.position_m, &[-r; 3], &[r; 3])?;
        unit_quat("orientation", 0, &self.orientation)?;
        scalar("range_min_m", self.range_min_m, 0.0, DEPTH_MAX_M)?;
        scalar("range_max_m", self.range_max_m, self.range_min_m, DEPTH_MAX_M)?;
        let n = self.n_instances as usize;
        if n > DEPTH_MAX_INSTANCES {
            return Err(ValidationError::Count {
                field: "n_instances",
                value: n as u64,
                max: DEPTH_MAX_INSTANCES as u64,
            });
        }
        let pixels = self.width as usize * self.height as usize;
        if let Some(index) = self.instance[..pixels].iter().position(|&k| k != DEPTH_ARM && k as usize > n) {
            return Err(ValidationError::OutOfRange {
                field: "instance",
                index,
                value: self.instance[index] as f64,
                min: 0.0,
                max: n as f64,
            });
        }
        Ok(())
    }
}

impl Validate for PlanStatus {
    fn validate(&self, _lim: &ContractLimits) -> Result<(), ValidationError> {
        if Fallback::from_u32(self.fallback).is_none() {
            return Err(ValidationError::BadEnum { field: "fallback", value: self.fallback });
        }
        if self.min_predicted_clearance_m.is_nan() {
            return Err(ValidationError::NonFinite { field: "min_predicted_clearance_m", index: 0 });
        }
        Ok(())
    }
}

impl Validate for PredictorProgress {
    fn validate(&self, _lim: &ContractLimits) -> Result<(), ValidationError> {
        // Frames are numbered from 0 by their one publisher: more frames consumed than
        // numbered is impossible.
        if self.frames > self.frame_seq.saturating_add(1) {
            return Err(ValidationError::Count {
                field: "frames",
                value: self.frames,
                max: self.frame_seq + 1,
            });
        }
        Ok(())
    }
}

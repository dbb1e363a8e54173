//! Online use: call [`Otg::update`] every control tick with the last output
//! state, like Ruckig's online mode; the trajectory is recomputed whenever
//! the target (or the limits/options) change.

use crate::{KinState, Limits, Options, OtgError, Trajectory};

/// Whether the motion is still under way after an update.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Status {
    Working,
    Finished,
}

/// The result of one [`Otg::update`] tick.
#[derive(Clone, Copy, Debug)]
pub struct Output<const N: usize> {
    /// The state to command for this tick (feed it back as `current` next tick).
    pub state: KinState<N>,
    pub jerk: [f64; N],
    /// Time along the current trajectory.
    pub time: f64,
    /// Duration of the current trajectory.
    pub duration: f64,
    /// The trajectory was (re)calculated during this tick.
    pub new_calculation: bool,
    pub status: Status,
}

/// Online trajectory generator with a fixed control period.
///
/// ```
/// use dkrrt_otg::{KinState, Limits, Options, Otg, Status};
/// let limits = Limits { v_max: [1.0; 6], a_max: [2.0; 6], j_max: [10.0; 6] };
/// let mut otg = Otg::new(limits, Options::default(), 0.001).unwrap();
/// let mut state = KinState::rest([0.0; 6]);
/// let target = KinState::rest([0.5, -0.2, 0.1, 0.0, 0.3, 0.0]);
/// loop {
///     let out = otg.update(&state, &target).unwrap();
///     state = out.state;
///     if out.status == Status::Finished { break; }
/// }
/// assert!((state.p[0] - 0.5).abs() < 1e-8);
/// ```
#[derive(Clone, Copy, Debug)]
pub struct Otg<const N: usize> {
    limits: Limits<N>,
    options: Options<N>,
    period: f64,
    traj: Option<Trajectory<N>>,
    target: KinState<N>,
    time: f64,
}

impl<const N: usize> Otg<N> {
    /// A generator ticking every `period` seconds (must be finite and > 0).
    pub fn new(limits: Limits<N>, options: Options<N>, period: f64) -> Result<Self, OtgError> {
        if !(period.is_finite() && period > 0.0) {
            return Err(OtgError::InvalidOption { which: "period", value: period });
        }
        crate::sync::validate_limits(&limits)?;
        crate::sync::validate_options(&options)?;
        Ok(Otg { limits, options, period, traj: None, target: KinState::default(), time: 0.0 })
    }

    /// Change the limits; the next update recalculates.
    pub fn set_limits(&mut self, limits: Limits<N>) {
        self.limits = limits;
        self.traj = None;
    }

    /// Change the options; the next update recalculates.
    pub fn set_options(&mut self, options: Options<N>) {
        self.options = options;
        self.traj = None;
    }

    /// The trajectory currently followed, if any.
    pub fn trajectory(&self) -> Option<&Trajectory<N>> {
        self.traj.as_ref()
    }

    /// Advance one control period. `current` is normally the previous
    /// output's state. Recalculates from `current` when `target` changed.
    pub fn update(&mut self, current: &KinState<N>, target: &KinState<N>) -> Result<Output<N>, OtgError> {
        let mut new_calculation = false;
        if self.traj.is_none() || *target != self.target {
            let tr = Trajectory::calculate(current, target, &self.limits, &self.options)?;
            self.traj = Some(tr);
            self.target = *target;
            self.time = 0.0;
            new_calculation = true;
        }
        let Some(tr) = self.traj.as_ref() else {
            return Err(OtgError::NoSolution { joint: 0 });
        };
        self.time += self.period;
        let s = tr.at(self.time);
        let status = if self.time >= tr.duration() { Status::Finished } else { Status::Working };
        Ok(Output {
            state: s.state(),
            jerk: s.j,
            time: self.time,
            duration: tr.duration(),
            new_calculation,
            status,
        })
    }
}

//! The simulator's tick as one core function, called by the `dkrrt sim` process and by the
//! in-process lockstep (`dkrrt eval`, `dkrrt study`): plant step, debris world step, the true
//! contact check on the arm's true state, and the sensor's observation frames.

use dkrrt_config::Scenario;
use dkrrt_model::ArmModel;
use dkrrt_msg::DebrisObservation;

use crate::debris::DebrisSide;
use crate::plant::{Plant, PlantConfig};

/// What a tick reports.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TickReport {
    /// This tick's check found a contact, and it is the run's first contact tick.
    pub first_contact: bool,
    /// Observation frames handed to `send`.
    pub frames: u32,
}

/// Plant + (optional) debris side, stepped together.
pub struct SimCore {
    pub plant: Plant,
    pub debris: Option<DebrisSide>,
    dt_s: f64,
}

impl SimCore {
    /// Builds the plant at `sim.initial_q` and the scenario's debris world (if any), and checks
    /// the initial configuration against the debris (allocates; start-up only).
    pub fn new(sc: &Scenario, model: ArmModel) -> Result<SimCore, String> {
        let debris = if sc.has_debris() { Some(DebrisSide::new(sc, &model)?) } else { None };
        let plant = Plant::new(model, PlantConfig::from_scenario(sc), &sc.sim.initial_q);
        let mut core = SimCore { plant, debris, dt_s: sc.period_ns() as f64 * 1e-9 };
        let q0 = core.plant.true_state().0.into();
        if let Some(d) = core.debris.as_mut() {
            d.check(&q0);
        }
        Ok(core)
    }

    /// One plant tick (the command for it was offered to the plant before): integrates the arm,
    /// advances the world by the same period, checks the true arm against the true debris and
    /// hands the sensor's due observation frames to `send`. Allocation-free.
    pub fn step<E>(
        &mut self,
        frame: &mut DebrisObservation,
        send: impl FnMut(&mut DebrisObservation) -> Result<(), E>,
    ) -> Result<TickReport, E> {
        self.plant.step();
        let mut rep = TickReport::default();
        if let Some(d) = self.debris.as_mut() {
            let q = self.plant.true_state().0.into();
            rep = d.tick(self.dt_s, &q, frame, send)?;
        }
        Ok(rep)
    }

    /// [`SimCore::step`] with the debris world stepped elsewhere (a copy of this core's debris
    /// side, built from the same scenario and stepped tick for tick): integrates the arm and
    /// checks it against that world's obstacles at plant time `t`. The sensor's frames are
    /// that copy's to hand on.
    pub fn step_against(&mut self, obstacles: &[dkrrt_collision::Obstacle], t: f64) -> TickReport {
        self.plant.step();
        let mut rep = TickReport::default();
        if let Some(d) = self.debris.as_mut() {
            let q = self.plant.true_state().0.into();
            rep.first_contact = d.check_against(&q, obstacles, t) && d.stats.contact_ticks == 1;
        }
        rep
    }
}

//! Sensor model: noisy, dropping, delayed debris pose observations at a fixed rate.
//!
//! Call [`Sensor::poll`] every simulation tick with the true states. When a sample instant is
//! due, every object is measured (stamped with the current true time), each measurement is
//! dropped with probability `dropout_prob`, noise is added, and the record is queued with a
//! release time `t + latency + U(0, latency_jitter)` (kept FIFO-monotone, like a transport
//! link). Records whose release time has passed are appended to the caller's [`ObsBuffer`].
//! Nothing allocates after [`Sensor::new`].

use crate::world::Debris;
use crate::MAX_DEBRIS;
use nalgebra::{UnitQuaternion, Vector3};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

/// One debris observation (plain data; the IPC message is defined elsewhere).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Observation {
    /// Debris id.
    pub id: u32,
    /// Measurement time (true time of the snapshot) [s].
    pub t: f64,
    /// Time at which the record became available to the consumer [s].
    pub t_avail: f64,
    /// Measured LVLH position [m].
    pub p: [f64; 3],
    /// Measured attitude body → LVLH, (w, x, y, z), unit norm, w ≥ 0.
    pub q: [f64; 4],
    /// Measured LVLH relative velocity [m/s] (valid if `has_rates`).
    pub v: [f64; 3],
    /// Measured body angular rate [rad/s] (valid if `has_rates`).
    pub w: [f64; 3],
    /// Whether `v` and `w` are filled.
    pub has_rates: bool,
    /// From a partial view (a camera's object cut by the frame or hidden in part): `p` is
    /// good only to about the object's size, `q` is measured only with `axis_only` (a rod's
    /// axis or a disc's normal from the visible part).
    pub partial: bool,
    /// The earlier records of this object came from views of part of it (`DEBRIS_RESTART`):
    /// its position and velocity estimate restarts from this one.
    pub restart: bool,
    /// `q` measures only the body z axis (`DEBRIS_AXIS_ONLY`: a rod's axis or a disc's normal
    /// seen by a camera): its
    /// spin about the axis and its sign are arbitrary.
    pub axis_only: bool,
    /// Sample sequence number (same for all records of one sample instant).
    pub seq: u32,
}

/// Sensor parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorConfig {
    /// Sample rate [Hz], 30–100.
    pub rate_hz: f64,
    /// Position noise std-dev per axis [m].
    pub pos_sigma: f64,
    /// Attitude noise std-dev per axis (small rotation) [rad].
    pub att_sigma: f64,
    /// Velocity noise std-dev per axis [m/s].
    pub vel_sigma: f64,
    /// Angular-rate noise std-dev per axis [rad/s].
    pub rate_sigma: f64,
    /// Report velocity and angular rate.
    pub report_rates: bool,
    /// Probability that an individual measurement is lost.
    pub dropout_prob: f64,
    /// Fixed latency [s].
    pub latency: f64,
    /// Additional uniform latency jitter [s].
    pub latency_jitter: f64,
    /// Objects farther than this from the sensor (the LVLH origin) are not observed [m] (a
    /// real sensor's range; also keeps every observation within the message contract).
    pub max_range: f64,
}

impl Default for SensorConfig {
    fn default() -> Self {
        SensorConfig {
            rate_hz: 50.0,
            pos_sigma: 0.01,
            att_sigma: 0.01,
            vel_sigma: 0.005,
            rate_sigma: 0.01,
            report_rates: false,
            dropout_prob: 0.02,
            latency: 0.03,
            latency_jitter: 0.01,
            max_range: 500.0,
        }
    }
}

/// Invalid sensor configuration (names the field).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("sensor field `{field}`: {reason}")]
pub struct SensorError {
    /// Offending field.
    pub field: &'static str,
    /// What is wrong.
    pub reason: String,
}

/// Capacity of the internal latency queue.
pub const QUEUE_CAP: usize = 32 * MAX_DEBRIS;
/// Samples in flight (the queue's batches): the most empty ones waiting for delivery.
const EMPTY_CAP: usize = QUEUE_CAP / MAX_DEBRIS;
/// Capacity of an [`ObsBuffer`].
pub const OBS_CAP: usize = 4 * MAX_DEBRIS;

/// Fixed-capacity output buffer of observations.
#[derive(Debug, Clone)]
pub struct ObsBuffer {
    items: [Observation; OBS_CAP],
    len: usize,
    /// Records that did not fit (lost) since creation.
    pub overflowed: u64,
}

impl Default for ObsBuffer {
    fn default() -> Self {
        ObsBuffer { items: [Observation::default(); OBS_CAP], len: 0, overflowed: 0 }
    }
}

impl ObsBuffer {
    /// Empty buffer.
    pub fn new() -> Self {
        Self::default()
    }
    /// Current records.
    pub fn as_slice(&self) -> &[Observation] {
        &self.items[..self.len]
    }
    /// Number of records.
    pub fn len(&self) -> usize {
        self.len
    }
    /// No records.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
    /// Remove all records.
    pub fn clear(&mut self) {
        self.len = 0;
    }
    fn push(&mut self, o: Observation) {
        if self.len < OBS_CAP {
            self.items[self.len] = o;
            self.len += 1;
        } else {
            self.overflowed += 1;
        }
    }
}

/// The sensor (state: schedule, RNG, latency queue).
#[derive(Debug, Clone)]
pub struct Sensor {
    cfg: SensorConfig,
    rng: SmallRng,
    next_sample: f64,
    seq: u32,
    queue: Box<[Observation; QUEUE_CAP]>,
    head: usize,
    len: usize,
    last_release: f64,
    /// Objects not observed because they were beyond `max_range`.
    pub out_of_range: u64,
    /// Measurements lost to dropout.
    pub dropped: u64,
    /// Measurements lost because the latency queue was full.
    pub queue_overflow: u64,
    /// When the samples that saw nothing (no object in range, every measurement lost) are
    /// delivered, oldest first: after the latency, without jitter (no noise is drawn for them,
    /// so the stream of the other samples stays the same). A ring: `empty_due[empty_head..]`,
    /// `empty_len` of them (at most one per sample in flight, fewer than the queue's batches).
    empty_due: [f64; EMPTY_CAP],
    empty_head: usize,
    empty_len: usize,
    /// A sample that saw nothing was delivered (see [`Sensor::take_empty_delivery`]).
    empty_delivered: bool,
}

fn gauss(rng: &mut SmallRng) -> f64 {
    let u1: f64 = rng.random::<f64>().max(1e-300);
    let u2: f64 = rng.random::<f64>();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

impl Sensor {
    /// Validate the configuration and create a sensor with a seeded noise stream.
    pub fn new(cfg: SensorConfig, seed: u64) -> Result<Self, SensorError> {
        let err = |field, reason: &str| Err(SensorError { field, reason: reason.to_string() });
        if !(cfg.rate_hz >= 30.0 && cfg.rate_hz <= 100.0) {
            return err("rate_hz", "must be in [30, 100] Hz");
        }
        for (f, v) in [
            ("pos_sigma", cfg.pos_sigma),
            ("att_sigma", cfg.att_sigma),
            ("vel_sigma", cfg.vel_sigma),
            ("rate_sigma", cfg.rate_sigma),
            ("latency", cfg.latency),
            ("latency_jitter", cfg.latency_jitter),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return err(f, "must be finite and >= 0");
            }
        }
        if !(cfg.max_range > 0.0) {
            return err("max_range", "must be > 0");
        }
        if !(0.0..=1.0).contains(&cfg.dropout_prob) {
            return err("dropout_prob", "must be in [0, 1]");
        }
        let batches = (QUEUE_CAP / MAX_DEBRIS) as f64;
        if (cfg.latency + cfg.latency_jitter) * cfg.rate_hz + 2.0 > batches {
            return err("latency", "latency × rate exceeds the fixed queue capacity");
        }
        Ok(Sensor {
            cfg,
            rng: SmallRng::seed_from_u64(seed),
            next_sample: 0.0,
            seq: 0,
            queue: Box::new([Observation::default(); QUEUE_CAP]),
            head: 0,
            len: 0,
            last_release: f64::NEG_INFINITY,
            dropped: 0,
            out_of_range: 0,
            queue_overflow: 0,
            empty_due: [0.0; EMPTY_CAP],
            empty_head: 0,
            empty_len: 0,
            empty_delivered: false,
        })
    }

    /// Configuration.
    pub fn config(&self) -> &SensorConfig {
        &self.cfg
    }

    /// Records waiting in the latency queue.
    pub fn pending(&self) -> usize {
        self.len
    }

    /// Sample (if due) and release delayed observations available at true time `t` into `out`.
    /// Returns the number of records appended. Allocation-free.
    pub fn poll(&mut self, t: f64, truth: &[Debris], out: &mut ObsBuffer) -> usize {
        if t + 1e-12 >= self.next_sample {
            let period = 1.0 / self.cfg.rate_hz;
            while self.next_sample <= t + 1e-12 {
                self.next_sample += period;
            }
            self.sample(t, truth);
        }
        let mut n = 0;
        while self.len > 0 && self.queue[self.head].t_avail <= t + 1e-12 {
            out.push(self.queue[self.head]);
            self.head = (self.head + 1) % QUEUE_CAP;
            self.len -= 1;
            n += 1;
        }
        while self.empty_len > 0 && self.empty_due[self.empty_head] <= t + 1e-12 {
            self.empty_head = (self.empty_head + 1) % EMPTY_CAP;
            self.empty_len -= 1;
            self.empty_delivered = true;
        }
        n
    }

    /// Whether a sample that saw nothing has been delivered since the last call: a perception
    /// chain says "looked, saw nothing" with an empty frame, so that an empty sky can be told
    /// from a silent sensor.
    pub fn take_empty_delivery(&mut self) -> bool {
        std::mem::take(&mut self.empty_delivered)
    }

    fn sample(&mut self, t: f64, truth: &[Debris]) {
        let c = self.cfg;
        let seq = self.seq;
        self.seq = self.seq.wrapping_add(1);
        let queued = self.len;
        for d in truth {
            if d.state.p.norm() > c.max_range {
                self.out_of_range += 1;
                continue;
            }
            if c.dropout_prob > 0.0 && self.rng.random::<f64>() < c.dropout_prob {
                self.dropped += 1;
                continue;
            }
            let r = &mut self.rng;
            let s = &d.state;
            let p = s.p + Vector3::new(gauss(r), gauss(r), gauss(r)) * c.pos_sigma;
            let dth = Vector3::new(gauss(r), gauss(r), gauss(r)) * c.att_sigma;
            let q = s.q * UnitQuaternion::from_scaled_axis(dth);
            let mut qq = [q.w, q.i, q.j, q.k];
            if qq[0] < 0.0 {
                qq.iter_mut().for_each(|x| *x = -*x);
            }
            let (v, w) = if c.report_rates {
                let v = s.v + Vector3::new(gauss(r), gauss(r), gauss(r)) * c.vel_sigma;
                let w = s.w + Vector3::new(gauss(r), gauss(r), gauss(r)) * c.rate_sigma;
                ([v.x, v.y, v.z], [w.x, w.y, w.z])
            } else {
                ([0.0; 3], [0.0; 3])
            };
            let jitter = if c.latency_jitter > 0.0 { c.latency_jitter * r.random::<f64>() } else { 0.0 };
            let t_avail = (t + c.latency + jitter).max(self.last_release);
            self.last_release = t_avail;
            let o = Observation {
                id: d.id,
                t,
                t_avail,
                p: [p.x, p.y, p.z],
                q: qq,
                v,
                w,
                has_rates: c.report_rates,
                partial: false,
                restart: false,
                axis_only: false,
                seq,
            };
            if self.len == QUEUE_CAP {
                self.queue_overflow += 1;
                continue;
            }
            let tail = (self.head + self.len) % QUEUE_CAP;
            self.queue[tail] = o;
            self.len += 1;
        }
        if self.len == queued && self.empty_len < EMPTY_CAP {
            self.empty_due[(self.empty_head + self.empty_len) % EMPTY_CAP] = t + c.latency;
            self.empty_len += 1;
        }
    }
}

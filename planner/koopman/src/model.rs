//! Linear lifted model `z⁺ = A z + B u`, snapshot data, EDMD / DMDc fits, forecast roll-out.

use crate::lifting::Lifting;
use crate::linalg::{lstsq, DMat, FitError, LstsqOptions};

/// A discrete-time Koopman model in a lifted space of dimension `p` with `m` inputs.
///
/// `[A B]` is stored column-major as one `p × (p + m)` block (`ab[j * p + i]`), so the
/// forecast is a sequence of contiguous axpys and [`crate::Rls`] updates it in place.
#[derive(Debug, Clone, PartialEq)]
pub struct KoopmanModel {
    /// State dimension `n` (the first `n` lifted coordinates are the state).
    pub n: usize,
    /// Lifted dimension `p`.
    pub p: usize,
    /// Input dimension `m`.
    pub m: usize,
    /// Sampling interval [s].
    pub dt: f64,
    /// `[A B]`, column-major, `p × (p + m)`.
    pub ab: Vec<f64>,
}

impl KoopmanModel {
    /// Zero model.
    pub fn zeros(n: usize, p: usize, m: usize, dt: f64) -> Self {
        KoopmanModel { n, p, m, dt, ab: vec![0.0; p * (p + m)] }
    }
    /// Build from `[A B]` as a `p × (p+m)` matrix.
    pub fn from_ab(n: usize, m: usize, dt: f64, ab: &DMat) -> Self {
        assert_eq!(ab.cols, ab.rows + m);
        KoopmanModel { n, p: ab.rows, m, dt, ab: ab.data.clone() }
    }
    /// Entry `A[i, j]`.
    pub fn a(&self, i: usize, j: usize) -> f64 {
        self.ab[j * self.p + i]
    }
    /// Entry `B[i, j]`.
    pub fn b(&self, i: usize, j: usize) -> f64 {
        self.ab[(self.p + j) * self.p + i]
    }
    /// `[A B]` as a dense matrix.
    pub fn ab_matrix(&self) -> DMat {
        DMat { rows: self.p, cols: self.p + self.m, data: self.ab.clone() }
    }
    /// `out = A z + B u` (`z.len() ≥ p`, `u.len() ≥ m`, `out.len() ≥ p`). Allocation-free.
    #[inline]
    pub fn step(&self, z: &[f64], u: &[f64], out: &mut [f64]) {
        let p = self.p;
        let out = &mut out[..p];
        out.iter_mut().for_each(|o| *o = 0.0);
        for (j, &zj) in z[..p].iter().chain(&u[..self.m]).enumerate() {
            if zj == 0.0 {
                continue;
            }
            let col = &self.ab[j * p..(j + 1) * p];
            for (o, a) in out.iter_mut().zip(col) {
                *o += a * zj;
            }
        }
    }
    /// Only the first `rows` outputs of `A z + B u` (the state rows when `rows = n`).
    #[inline]
    pub fn step_rows(&self, rows: usize, z: &[f64], u: &[f64], out: &mut [f64]) {
        let p = self.p;
        let out = &mut out[..rows];
        out.iter_mut().for_each(|o| *o = 0.0);
        for (j, &zj) in z[..p].iter().chain(&u[..self.m]).enumerate() {
            let col = &self.ab[j * p..j * p + rows];
            for (o, a) in out.iter_mut().zip(col) {
                *o += a * zj;
            }
        }
    }
}

/// Snapshot pairs `(x_k, x_k⁺, u_k)`, sample-major (row `k` of each block is one sample).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Snapshots {
    /// State dimension.
    pub n: usize,
    /// Input dimension.
    pub m: usize,
    /// `N × n` current states.
    pub x: Vec<f64>,
    /// `N × n` successor states.
    pub y: Vec<f64>,
    /// `N × m` inputs.
    pub u: Vec<f64>,
}

impl Snapshots {
    /// Empty set.
    pub fn new(n: usize, m: usize) -> Self {
        Snapshots { n, m, ..Default::default() }
    }
    /// Number of pairs.
    pub fn len(&self) -> usize {
        self.x.len().checked_div(self.n).unwrap_or(0)
    }
    /// No pairs.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Add one pair.
    pub fn push(&mut self, x: &[f64], y: &[f64], u: &[f64]) {
        self.x.extend_from_slice(&x[..self.n]);
        self.y.extend_from_slice(&y[..self.n]);
        self.u.extend_from_slice(&u[..self.m]);
    }
    /// Add all consecutive pairs of a trajectory (`T × n` row-major) with inputs (`(T-1) × m`).
    pub fn push_trajectory(&mut self, traj: &[f64], inputs: &[f64]) {
        let t = traj.len() / self.n;
        for k in 0..t.saturating_sub(1) {
            let u = &inputs[k * self.m..(k + 1) * self.m];
            self.push(&traj[k * self.n..(k + 1) * self.n], &traj[(k + 1) * self.n..(k + 2) * self.n], u);
        }
    }
    /// Sample `k`: (x, y, u).
    pub fn get(&self, k: usize) -> (&[f64], &[f64], &[f64]) {
        let (n, m) = (self.n, self.m);
        (&self.x[k * n..(k + 1) * n], &self.y[k * n..(k + 1) * n], &self.u[k * m..(k + 1) * m])
    }
}

/// Lift data into the regressor matrix `Ωᵀ = [φ(x_k)ᵀ u_kᵀ]` (N × (p+m)) and target `φ(y_k)ᵀ` (N × p).
pub fn lifted_data(lifting: &dyn Lifting, data: &Snapshots) -> (DMat, DMat) {
    let (p, m, nn) = (lifting.dim(), data.m, data.len());
    let mut omega = DMat::zeros(nn, p + m);
    let mut target = DMat::zeros(nn, p);
    let mut buf = vec![0.0; p];
    for k in 0..nn {
        let (x, y, u) = data.get(k);
        lifting.lift(x, &mut buf);
        for (j, v) in buf.iter().enumerate() {
            omega.set(k, j, *v);
        }
        for (j, v) in u.iter().enumerate() {
            omega.set(k, p + j, *v);
        }
        lifting.lift(y, &mut buf);
        for (j, v) in buf.iter().enumerate() {
            target.set(k, j, *v);
        }
    }
    (omega, target)
}

/// EDMD (m = 0) / EDMD with control (DMDc, m > 0): `[A B] = φ(Ξ′) Ω†`, `Ω = [φ(Ξ); Υ]`,
/// solved by truncated SVD (faer). Returns the model and the numerical rank used.
pub fn fit_edmd(
    lifting: &dyn Lifting,
    data: &Snapshots,
    dt: f64,
    opts: &LstsqOptions,
) -> Result<(KoopmanModel, usize), FitError> {
    if data.n != lifting.state_dim() {
        return Err(FitError::Dim(format!("data n = {} but lifting n = {}", data.n, lifting.state_dim())));
    }
    if data.is_empty() {
        return Err(FitError::NotEnoughData("no snapshot pairs".into()));
    }
    let (omega, target) = lifted_data(lifting, data);
    let (theta_t, rank) = lstsq(&omega, &target, opts)?; // (p+m) × p
    Ok((KoopmanModel::from_ab(data.n, data.m, dt, &theta_t.transpose()), rank))
}

/// Plain DMD with control on the raw state (lifting = identity + constant is
/// [`crate::Polynomial::new`]`(n, 1)`); provided as a named entry point.
pub fn fit_dmdc(data: &Snapshots, dt: f64, opts: &LstsqOptions) -> Result<(KoopmanModel, usize), FitError> {
    fit_edmd(&crate::lifting::Polynomial::new(data.n, 1), data, dt, opts)
}

/// Roll-out mode of a forecast.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rollout {
    /// Iterate the linear model in the lifted space: `z⁺ = A z + B u`, decode `x = z[..n]`.
    /// Cost `O(p²)` per step.
    Linear,
    /// Re-lift the decoded state every step: `x⁺ = (A φ(x) + B u)[..n]`. Cost `O(n p)` + lift.
    Relift,
}

/// Post-processing of decoded states during a forecast.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum StateConstraint {
    /// None.
    #[default]
    None,
    /// Renormalise the unit quaternion stored at `x[at..at+4]`.
    UnitQuaternion {
        /// Offset of the quaternion in the state vector.
        at: usize,
    },
}

impl StateConstraint {
    /// Apply to a state vector in place.
    #[inline]
    pub fn apply(&self, x: &mut [f64]) {
        if let StateConstraint::UnitQuaternion { at } = *self {
            let q = &mut x[at..at + 4];
            let nq = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
            if nq > 1e-12 {
                q.iter_mut().for_each(|v| *v /= nq);
            }
        }
    }
}

/// Preallocated scratch for forecasting with one model size. `forecast*` never allocate.
#[derive(Debug, Clone)]
pub struct Forecaster {
    z: Vec<f64>,
    zn: Vec<f64>,
    x: Vec<f64>,
    /// Row-major copy of the state rows of `[A B]` (relift mode).
    rows: Vec<f64>,
    /// Constraint applied to every decoded state.
    pub constraint: StateConstraint,
}

/// Maximum input dimension `m` supported by [`Forecaster`].
pub const MAX_INPUTS: usize = 8;

#[inline]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    // Four independent accumulators so the reduction pipelines / vectorises.
    let (mut s0, mut s1, mut s2, mut s3) = (0.0, 0.0, 0.0, 0.0);
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        s0 += x[0] * y[0];
        s1 += x[1] * y[1];
        s2 += x[2] * y[2];
        s3 += x[3] * y[3];
    }
    let mut s = (s0 + s1) + (s2 + s3);
    for (x, y) in ra.iter().zip(rb) {
        s += x * y;
    }
    s
}

impl Forecaster {
    /// Scratch for models of lifted dimension ≤ `p_max` and at most [`MAX_INPUTS`] inputs.
    pub fn new(p_max: usize) -> Self {
        let w = p_max + MAX_INPUTS;
        Forecaster {
            z: vec![0.0; w],
            zn: vec![0.0; w],
            x: vec![0.0; w],
            rows: vec![0.0; p_max * w],
            constraint: StateConstraint::None,
        }
    }
    /// With a state constraint.
    pub fn with_constraint(mut self, c: StateConstraint) -> Self {
        self.constraint = c;
        self
    }

    /// Linear roll-out from a lifted state `z0` with constant input `u`: writes
    /// `H = out.len() / n` decoded states `x_1..x_H` row-major into `out`. Returns `H`.
    pub fn forecast_lifted(&mut self, model: &KoopmanModel, z0: &[f64], u: &[f64], out: &mut [f64]) -> usize {
        let p = model.p;
        assert!(self.z.len() >= p, "Forecaster scratch too small");
        self.z[..p].copy_from_slice(&z0[..p]);
        self.roll_linear(model, u, out)
    }

    fn roll_linear(&mut self, model: &KoopmanModel, u: &[f64], out: &mut [f64]) -> usize {
        let n = model.n;
        let h = out.len() / n;
        for k in 0..h {
            model.step(&self.z, u, &mut self.zn);
            std::mem::swap(&mut self.z, &mut self.zn);
            let xk = &mut out[k * n..(k + 1) * n];
            xk.copy_from_slice(&self.z[..n]);
            self.constraint.apply(xk);
        }
        h
    }

    /// Roll-out from a state `x0` (lifted internally) in the given mode; output as in
    /// [`Forecaster::forecast_lifted`]. Returns `H`.
    pub fn forecast(
        &mut self,
        model: &KoopmanModel,
        lifting: &dyn Lifting,
        x0: &[f64],
        u: &[f64],
        mode: Rollout,
        out: &mut [f64],
    ) -> usize {
        let (n, p) = (model.n, model.p);
        assert!(self.z.len() >= p, "Forecaster scratch too small");
        lifting.lift(x0, &mut self.z);
        match mode {
            Rollout::Linear => self.roll_linear(model, u, out),
            Rollout::Relift => {
                let h = out.len() / n;
                let (m, w) = (model.m, p + model.m);
                assert!(m <= MAX_INPUTS, "Forecaster supports at most MAX_INPUTS inputs");
                // Row-major copy of the n state rows: each step is n contiguous dot products.
                for i in 0..n {
                    for j in 0..w {
                        self.rows[i * w + j] = model.ab[j * p + i];
                    }
                }
                for k in 0..h {
                    self.z[p..w].copy_from_slice(&u[..m]);
                    for i in 0..n {
                        self.x[i] = dot(&self.rows[i * w..(i + 1) * w], &self.z[..w]);
                    }
                    self.constraint.apply(&mut self.x[..n]);
                    out[k * n..(k + 1) * n].copy_from_slice(&self.x[..n]);
                    if k + 1 < h {
                        lifting.lift(&self.x[..n], &mut self.z);
                    }
                }
                h
            }
        }
    }
}

//! The paper's dual-data Koopman scheme (Sec. "Methodology").
//!
//! 1. **Generator from collocation data** `D_β = {ξ_i, υ_i}` of the *known* nominal dynamics
//!    `ξ̇ = F(ξ, υ)`: with `Θ(ξ, υ) = [φ(ξ); υ]` and `Θ̇ = [Dφ(ξ)·F(ξ, υ); 0]` (zero-order-hold
//!    input), `L = argmin ‖Θ̇ − L Θ‖ = Θ̇ Θ†`. The half-step propagator is
//!    `K_{Δτ/2} = exp(L Δτ/2)` (scaling-and-squaring instead of the paper's eigendecomposition:
//!    same operator, robust for defective / complex spectra; `K⁻¹ = exp(−L Δτ/2)` is exact).
//! 2. **Correction from trajectory data** `D_α = {ξ_k, ξ_k⁺, υ_k}`: with `X = K_{Δτ/2} Θ(Ξ, Υ)`
//!    and `Y = K_{Δτ/2}⁻¹ Θ(Ξ′, Υ)`, `H = argmin ‖H X − Y‖`. We solve for `H = I + Δ`
//!    (`Δ = (Y − X) X†`, truncated SVD / ridge): identical to the paper's
//!    `H ≈ K⁻¹Θ(Ξ′)(KΘ(Ξ))†` when `X` has full row rank, and shrinks towards the nominal
//!    model (`H = I`) instead of towards zero when trajectory data are scarce.
//! 3. The one-step operator is the symmetric composition `K_{Δτ/2} H K_{Δτ/2}`; its first `p`
//!    rows are the `[A B]` of a [`KoopmanModel`].
//!
//! Ablation: [`DualVariant::NominalOnly`] (`H = I`), [`DualVariant::Corrected`], and plain
//! trajectory-only EDMD ([`crate::fit_edmd`]) can be compared on the same data.

use crate::lifting::Lifting;
use crate::linalg::{lstsq, DMat, FitError, LstsqOptions};
use crate::model::{KoopmanModel, Snapshots};

/// Continuous-time Koopman generator `L` on `Θ = [φ(ξ); υ]` (`d × d`, `d = p + m`).
#[derive(Debug, Clone, PartialEq)]
pub struct Generator {
    /// State dimension.
    pub n: usize,
    /// Lifted dimension.
    pub p: usize,
    /// Input dimension.
    pub m: usize,
    /// Generator matrix.
    pub l: DMat,
    /// Numerical rank of the regression.
    pub rank: usize,
}

impl Generator {
    /// Propagator `exp(L τ)`.
    pub fn propagator(&self, tau: f64) -> DMat {
        self.l.scale(tau).expm()
    }
}

/// Fit the generator of the known dynamics `f(x, u, ẋ)` from collocation points
/// (`xs`: `N × n`, `us`: `N × m`, row-major).
pub fn fit_generator(
    lifting: &dyn Lifting,
    xs: &[f64],
    us: &[f64],
    m: usize,
    f: impl Fn(&[f64], &[f64], &mut [f64]),
    opts: &LstsqOptions,
) -> Result<Generator, FitError> {
    let (n, p) = (lifting.state_dim(), lifting.dim());
    let nn = xs.len() / n;
    if xs.len() != nn * n || us.len() != nn * m {
        return Err(FitError::Dim("collocation x must be N × n and u N × m".into()));
    }
    if nn == 0 {
        return Err(FitError::NotEnoughData("no collocation points".into()));
    }
    let d = p + m;
    let mut theta = DMat::zeros(nn, d);
    let mut dtheta = DMat::zeros(nn, d);
    let (mut phi, mut dphi, mut xdot) = (vec![0.0; p], vec![0.0; p], vec![0.0; n]);
    for k in 0..nn {
        let x = &xs[k * n..(k + 1) * n];
        let u = &us[k * m..(k + 1) * m];
        f(x, u, &mut xdot);
        lifting.lift(x, &mut phi);
        lifting.lift_derivative(x, &xdot, &mut dphi);
        for j in 0..p {
            theta.set(k, j, phi[j]);
            dtheta.set(k, j, dphi[j]);
        }
        for j in 0..m {
            theta.set(k, p + j, u[j]);
        }
    }
    let (lt, rank) = lstsq(&theta, &dtheta, opts)?;
    Ok(Generator { n, p, m, l: lt.transpose(), rank })
}

/// Which dual-data variant to build (ablation).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DualVariant {
    /// Nominal generator only: `K_{Δτ/2} K_{Δτ/2}` (`H = I`).
    NominalOnly,
    /// Nominal generator plus the correction `H` learned from trajectory data.
    Corrected,
}

/// Result of [`fit_dual`].
#[derive(Debug, Clone, PartialEq)]
pub struct DualFit {
    /// Half-step nominal propagator `exp(L Δτ/2)` (`d × d`).
    pub k_half: DMat,
    /// Correction `H` (`d × d`; identity for [`DualVariant::NominalOnly`]).
    pub h: DMat,
    /// The resulting one-step model (`[A B]` = first `p` rows of `K H K`).
    pub model: KoopmanModel,
    /// Rank used in the correction regression (0 for nominal-only).
    pub rank: usize,
}

/// Build the dual-data model with step `dt` from a generator and trajectory snapshots.
pub fn fit_dual(
    lifting: &dyn Lifting,
    gen: &Generator,
    traj: &Snapshots,
    dt: f64,
    variant: DualVariant,
    opts: &LstsqOptions,
) -> Result<DualFit, FitError> {
    let (n, p, m) = (gen.n, gen.p, gen.m);
    if lifting.dim() != p || lifting.state_dim() != n || traj.n != n || traj.m != m {
        return Err(FitError::Dim("lifting / generator / trajectory dimensions differ".into()));
    }
    let d = p + m;
    let k_half = gen.propagator(0.5 * dt);
    let (h, rank) = match variant {
        DualVariant::NominalOnly => (DMat::identity(d), 0),
        DualVariant::Corrected => {
            if traj.is_empty() {
                return Err(FitError::NotEnoughData("no trajectory pairs for the correction".into()));
            }
            let k_inv = gen.propagator(-0.5 * dt);
            let nn = traj.len();
            // Θ(Ξ,Υ) and Θ(Ξ′,Υ) as d × N.
            let mut th = DMat::zeros(d, nn);
            let mut th1 = DMat::zeros(d, nn);
            let mut buf = vec![0.0; p];
            for k in 0..nn {
                let (x, y, u) = traj.get(k);
                lifting.lift(x, &mut buf);
                th.data[k * d..k * d + p].copy_from_slice(&buf);
                th.data[k * d + p..(k + 1) * d].copy_from_slice(u);
                lifting.lift(y, &mut buf);
                th1.data[k * d..k * d + p].copy_from_slice(&buf);
                th1.data[k * d + p..(k + 1) * d].copy_from_slice(u);
            }
            let x = k_half.mul(&th);
            let y = k_inv.mul(&th1);
            let resid = y.add_scaled(&x, -1.0);
            let (delta_t, rank) = lstsq(&x.transpose(), &resid.transpose(), opts)?;
            (DMat::identity(d).add_scaled(&delta_t.transpose(), 1.0), rank)
        }
    };
    let total = k_half.mul(&h).mul(&k_half);
    let ab = DMat::from_fn(p, d, |i, j| total.get(i, j));
    Ok(DualFit { k_half, h, model: KoopmanModel::from_ab(n, m, dt, &ab), rank })
}

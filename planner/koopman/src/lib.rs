//! dkrrt-koopman: Koopman operator library for debris motion prediction (DK-RRT).
//!
//! * [`lifting`]: the [`Lifting`] dictionary trait (state-inclusive: `φ(x) = [x, …]`) with
//!   [`Polynomial`], [`Rbf`] and [`Fourier`] dictionaries; learned liftings plug in later.
//! * [`model`]: [`KoopmanModel`] (`z⁺ = A z + B u`), [`fit_edmd`] / [`fit_dmdc`]
//!   (`Θ = Ξ′_φ Ω†` by truncated SVD with faer), allocation-free [`Forecaster`].
//! * [`dual`]: the paper's dual-data scheme (nominal generator from collocation data + learned
//!   correction `H`), with the nominal-only variant for the ablation.
//! * [`rls`]: allocation-free recursive least squares with forgetting, guarded.
//! * [`bound`]: per-horizon [`ErrorBound`] from validation residuals, grown after events.
//! * [`baseline`]: [`ConstantVelocity`] predictor. [`debris_state`]: the 13-state layout.
//!
//! Memory model: matrices are heap-allocated once when a model is fitted or a workspace is
//! built (sized by the model's `p`, `m`); [`Forecaster::forecast`], [`Rls::update`],
//! [`ErrorBound::radius`]/`grow`/`relax` and [`ConstantVelocity::forecast`] never allocate.
//! Only `ErrorBound` uses a compile-time maximum ([`bound::MAX_HORIZON`]).

// Index loops mirror the matrix formulas; negated comparisons deliberately treat NaN as bad.
#![allow(clippy::needless_range_loop, clippy::too_many_arguments, clippy::neg_cmp_op_on_partial_ord)]

pub mod baseline;
pub mod bound;
pub mod debris_state;
pub mod dual;
pub mod lifting;
pub mod linalg;
pub mod model;
pub mod rls;

pub use baseline::ConstantVelocity;
pub use bound::{validation_errors, ErrorBound, MAX_HORIZON};
pub use dual::{fit_dual, fit_generator, DualFit, DualVariant, Generator};
pub use lifting::{exp_consts, exp_fast, Fourier, Lifting, Polynomial, Rbf, RbfKind};
pub use linalg::{DMat, FitError, LstsqOptions};
pub use model::{
    fit_dmdc, fit_edmd, lifted_data, Forecaster, KoopmanModel, Rollout, Snapshots, StateConstraint,
};
pub use rls::{Rls, RlsConfig, RlsStatus};

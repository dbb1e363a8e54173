//! dkrrt-deep: Deep Koopman (DK-DMD) for debris motion prediction.
//!
//! * [`DeepLifting`]: the learned lifting `φ(x) = [x, NN(x)]` (state first, so the decoder is
//!   `[I 0]`), an MLP with `tanh` hidden layers whose weights live in fixed-size arrays;
//!   implements [`dkrrt_koopman::Lifting`] with an allocation-free `lift`.
//! * [`train`]: the paper's Algorithm 1 with candle (CPU, f64): multi-step prediction loss over a
//!   horizon `H` plus lifted consistency, `K` re-solved by ridge least squares every `M` epochs
//!   and trained by Adam in between, best-on-validation parameters returned.
//! * [`DeepKoopman`]: lifting + [`dkrrt_koopman::KoopmanModel`] (`p = n + extra`, `m = 0`), usable
//!   with [`dkrrt_koopman::Forecaster`] and [`dkrrt_koopman::Rls`].
//! * [`file`]: versioned, checksummed model files holding several named models
//!   ([`save_models`], [`load_models`], [`to_bytes`], [`from_bytes`]); format in the README.

// Negated comparisons deliberately treat NaN as invalid.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord, clippy::nonminimal_bool)]

pub mod file;
pub mod lifting;
pub mod testdata;
pub mod train;

pub use file::{
    from_bytes, load_model, load_models, save_models, select, to_bytes, ModelFileError, FORMAT_VERSION, MAGIC,
};
pub use lifting::{
    param_count, tanh_fast, DeepLifting, LiftingError, MAX_EXTRA, MAX_HIDDEN, MAX_IN, MAX_LAYERS, MAX_PARAMS,
};
pub use train::{rmse_per_step, train, Progress, TrainConfig, TrainData, TrainError, TrainReport};

/// A trained deep Koopman model: lifting and linear lifted dynamics `z⁺ = A z`.
#[derive(Clone, Debug)]
pub struct DeepKoopman {
    /// `φ(x) = [x, NN(x)]`.
    pub lifting: DeepLifting,
    /// `n`, `p = n + extra`, `m = 0`, `dt`, `A` (column-major `p × p`).
    pub model: dkrrt_koopman::KoopmanModel,
}

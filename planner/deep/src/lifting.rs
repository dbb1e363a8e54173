//! Fixed-array, allocation-free MLP lifting `φ(x) = [x, NN(x)]`.

use dkrrt_koopman::Lifting;

/// Maximum state dimension `n`.
pub const MAX_IN: usize = 16;
/// Maximum width of a hidden layer.
pub const MAX_HIDDEN: usize = 64;
/// Maximum number of hidden layers.
pub const MAX_LAYERS: usize = 3;
/// Maximum number of extra observables (`p = n + extra`).
pub const MAX_EXTRA: usize = 32;
/// Size of the fixed parameter buffer (all layers at their maximum size, weights + biases).
pub const MAX_PARAMS: usize = MAX_HIDDEN * (MAX_IN + 1)
    + (MAX_LAYERS - 1) * MAX_HIDDEN * (MAX_HIDDEN + 1)
    + MAX_EXTRA * (MAX_HIDDEN + 1);

/// Why a set of lifting dimensions or parameters is not accepted.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LiftingError {
    /// A dimension outside its compile-time range.
    #[error("{field} = {value} out of range {min}..={max}")]
    OutOfRange {
        /// Which dimension.
        field: &'static str,
        /// Its value.
        value: usize,
        /// Smallest allowed.
        min: usize,
        /// Largest allowed.
        max: usize,
    },
    /// A slice of the wrong length.
    #[error("{field} has length {found}, expected {expected}")]
    Length {
        /// Which slice.
        field: &'static str,
        /// Its length.
        found: usize,
        /// Required length.
        expected: usize,
    },
    /// NaN or infinite entry (or a scale that is not strictly positive).
    #[error("invalid value in {field}[{index}]")]
    Invalid {
        /// Which slice.
        field: &'static str,
        /// Index of the first bad entry.
        index: usize,
    },
}

/// Number of MLP parameters (weights + biases) of a network `n → hidden (× layers) → extra`.
pub fn param_count(n: usize, hidden: usize, layers: usize, extra: usize) -> usize {
    hidden * (n + 1) + layers.saturating_sub(1) * hidden * (hidden + 1) + extra * (hidden + 1)
}

/// Learned lifting `φ(x) = [x, NN(x)]` with `NN(x) = W_L tanh(… tanh(W_1 u + b_1) …) + b_L`
/// applied to the normalised input `u_i = (x_i − offset_i) / scale_i`.
///
/// Parameters live in one fixed array (no heap): layer by layer, each layer's weight matrix
/// row-major (`out × in`) followed by its bias. [`Lifting::lift`] never allocates.
#[derive(Clone, Debug)]
pub struct DeepLifting {
    n: usize,
    hidden: usize,
    layers: usize,
    extra: usize,
    offset: [f64; MAX_IN],
    scale: [f64; MAX_IN],
    inv_scale: [f64; MAX_IN],
    params: [f64; MAX_PARAMS],
}

fn check_range(field: &'static str, value: usize, min: usize, max: usize) -> Result<(), LiftingError> {
    if value < min || value > max {
        return Err(LiftingError::OutOfRange { field, value, min, max });
    }
    Ok(())
}

impl DeepLifting {
    /// Build from dimensions, input normalisation and the flat parameter list (layout as in the
    /// type docs; length [`param_count`]).
    pub fn new(
        n: usize,
        hidden: usize,
        layers: usize,
        extra: usize,
        offset: &[f64],
        scale: &[f64],
        params: &[f64],
    ) -> Result<Self, LiftingError> {
        check_range("n", n, 1, MAX_IN)?;
        check_range("hidden", hidden, 1, MAX_HIDDEN)?;
        check_range("layers", layers, 1, MAX_LAYERS)?;
        check_range("extra", extra, 1, MAX_EXTRA)?;
        for (field, s) in [("offset", offset), ("scale", scale)] {
            if s.len() != n {
                return Err(LiftingError::Length { field, found: s.len(), expected: n });
            }
        }
        let np = param_count(n, hidden, layers, extra);
        if params.len() != np {
            return Err(LiftingError::Length { field: "params", found: params.len(), expected: np });
        }
        if let Some(index) = offset.iter().position(|v| !v.is_finite()) {
            return Err(LiftingError::Invalid { field: "offset", index });
        }
        if let Some(index) = scale.iter().position(|v| !(v.is_finite() && *v > 0.0 && (1.0 / v).is_finite()))
        {
            return Err(LiftingError::Invalid { field: "scale", index });
        }
        if let Some(index) = params.iter().position(|v| !v.is_finite()) {
            return Err(LiftingError::Invalid { field: "params", index });
        }
        let mut l = DeepLifting {
            n,
            hidden,
            layers,
            extra,
            offset: [0.0; MAX_IN],
            scale: [1.0; MAX_IN],
            inv_scale: [1.0; MAX_IN],
            params: [0.0; MAX_PARAMS],
        };
        l.offset[..n].copy_from_slice(offset);
        l.scale[..n].copy_from_slice(scale);
        for i in 0..n {
            l.inv_scale[i] = 1.0 / scale[i];
        }
        l.params[..np].copy_from_slice(params);
        Ok(l)
    }
    /// Hidden layer width.
    pub fn hidden(&self) -> usize {
        self.hidden
    }
    /// Number of hidden layers.
    pub fn layers(&self) -> usize {
        self.layers
    }
    /// Number of extra observables (`dim() − state_dim()`).
    pub fn extra(&self) -> usize {
        self.extra
    }
    /// Input offsets (length `n`).
    pub fn offset(&self) -> &[f64] {
        &self.offset[..self.n]
    }
    /// Input scales (length `n`).
    pub fn scale(&self) -> &[f64] {
        &self.scale[..self.n]
    }
    /// Flat parameters (length [`param_count`]).
    pub fn params(&self) -> &[f64] {
        &self.params[..param_count(self.n, self.hidden, self.layers, self.extra)]
    }
    /// `NN(x)` only: writes `extra` values into `out`. Allocation-free. Always inlined, so a
    /// caller compiled with wider vector units (e.g. `#[target_feature(enable = "avx2")]`)
    /// gets this code compiled for them (`dkrrt-predictor`'s roll-out engine does).
    #[inline(always)]
    pub fn features(&self, x: &[f64], out: &mut [f64]) {
        let (n, h) = (self.n, self.hidden);
        let mut u = [0.0f64; MAX_IN];
        for i in 0..n {
            u[i] = (x[i] - self.offset[i]) * self.inv_scale[i];
        }
        let mut a = [0.0f64; MAX_HIDDEN];
        let mut b = [0.0f64; MAX_HIDDEN];
        let mut off = 0;
        off = dense(&self.params, off, &u[..n], &mut a[..h], true);
        for _ in 1..self.layers {
            off = dense(&self.params, off, &a[..h], &mut b[..h], true);
            std::mem::swap(&mut a, &mut b);
        }
        dense(&self.params, off, &a[..h], &mut out[..self.extra], false);
    }
}

#[inline(always)]
fn dot(w: &[f64], x: &[f64]) -> f64 {
    let (mut s0, mut s1, mut s2, mut s3) = (0.0, 0.0, 0.0, 0.0);
    let (cw, cx) = (w.chunks_exact(4), x.chunks_exact(4));
    let (rw, rx) = (cw.remainder(), cx.remainder());
    for (a, b) in cw.zip(cx) {
        s0 += a[0] * b[0];
        s1 += a[1] * b[1];
        s2 += a[2] * b[2];
        s3 += a[3] * b[3];
    }
    let mut s = (s0 + s1) + (s2 + s3);
    for (a, b) in rw.iter().zip(rx) {
        s += a * b;
    }
    s
}

/// `out = act(W x + b)` with `W` row-major at `params[off..]`, `b` after it. Returns the offset
/// of the next layer.
#[inline(always)]
fn dense(params: &[f64], off: usize, x: &[f64], out: &mut [f64], act: bool) -> usize {
    let (ni, no) = (x.len(), out.len());
    let w = &params[off..off + no * ni];
    let b = &params[off + no * ni..off + no * ni + no];
    for ((o, row), bi) in out.iter_mut().zip(w.chunks_exact(ni)).zip(b) {
        *o = dot(row, x) + bi;
    }
    if act {
        // Separate branch-free pass so it vectorises.
        for o in out.iter_mut() {
            *o = tanh_fast(*o);
        }
    }
    off + no * (ni + 1)
}

/// `exp(y)` for `y ≤ 0` (clamped at −700), branch-free: `y = k ln 2 + r`, `|r| ≤ ln 2 / 2`,
/// degree-13 Taylor polynomial for `e^r` (truncation < 2e-16), `2^k` by exponent bits.
#[inline(always)]
fn exp_nonpos(y: f64) -> f64 {
    const LOG2E: f64 = std::f64::consts::LOG2_E;
    const LN2_HI: f64 = f64::from_bits(0x3fe6_2e42_fee0_0000); // fdlibm ln2_hi
    const LN2_LO: f64 = f64::from_bits(0x3dea_39ef_3579_3c76); // fdlibm ln2_lo
    const MAGIC: f64 = 6_755_399_441_055_744.0; // 1.5 · 2^52: adding it rounds to an integer
    let y = y.max(-700.0);
    let t = y * LOG2E + MAGIC;
    let k = t - MAGIC;
    let ki = (t.to_bits() as i64).wrapping_sub(MAGIC.to_bits() as i64);
    let r = (y - k * LN2_HI) - k * LN2_LO;
    let mut p = 1.0 / 6_227_020_800.0; // 1/13!
    for c in [
        1.0 / 479_001_600.0,
        1.0 / 39_916_800.0,
        1.0 / 3_628_800.0,
        1.0 / 362_880.0,
        1.0 / 40_320.0,
        1.0 / 5_040.0,
        1.0 / 720.0,
        1.0 / 120.0,
        1.0 / 24.0,
        1.0 / 6.0,
        0.5,
        1.0,
        1.0,
    ] {
        p = p * r + c;
    }
    p * f64::from_bits(((ki + 1023) as u64) << 52)
}

/// `tanh(x)` to within a few ulp of `f64::tanh`, branch-free (vectorisable):
/// `(1 − e)/(1 + e)` with `e = exp(−2|x|)`, odd Taylor series for `|x| < 1/16`.
#[inline(always)]
pub fn tanh_fast(x: f64) -> f64 {
    let a = x.abs();
    let e = exp_nonpos(-2.0 * a);
    let big = (1.0 - e) / (1.0 + e);
    let x2 = a * a;
    let small = a
        * (1.0
            + x2 * (-1.0 / 3.0
                + x2 * (2.0 / 15.0
                    + x2 * (-17.0 / 315.0 + x2 * (62.0 / 2835.0 + x2 * (-1382.0 / 155_925.0))))));
    // NaN fails both comparisons and is passed through.
    let t = if a < 0.0625 {
        small
    } else if a >= 0.0625 {
        big
    } else {
        a
    };
    t.copysign(x)
}

impl Lifting for DeepLifting {
    fn state_dim(&self) -> usize {
        self.n
    }
    fn dim(&self) -> usize {
        self.n + self.extra
    }
    #[inline]
    fn lift(&self, x: &[f64], out: &mut [f64]) {
        let n = self.n;
        out[..n].copy_from_slice(&x[..n]);
        self.features(x, &mut out[n..n + self.extra]);
    }
}

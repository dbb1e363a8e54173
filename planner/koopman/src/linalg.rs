//! Small dense linear algebra for fitting (allocates; never used in hot paths):
//! a column-major matrix, truncated-SVD / ridge least squares (faer), matrix exponential.

/// Error of a fit.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FitError {
    /// Inconsistent dimensions.
    #[error("dimension mismatch: {0}")]
    Dim(String),
    /// Not enough samples.
    #[error("not enough data: {0}")]
    NotEnoughData(String),
    /// Non-finite values in the data.
    #[error("non-finite value in {0}")]
    NonFinite(&'static str),
    /// The SVD did not converge.
    #[error("SVD failed to converge")]
    Svd,
}

/// Dense column-major matrix (fitting only).
#[derive(Debug, Clone, PartialEq)]
pub struct DMat {
    /// Rows.
    pub rows: usize,
    /// Columns.
    pub cols: usize,
    /// Column-major entries, `data[j * rows + i]`.
    pub data: Vec<f64>,
}

impl DMat {
    /// Zero matrix.
    pub fn zeros(rows: usize, cols: usize) -> Self {
        DMat { rows, cols, data: vec![0.0; rows * cols] }
    }
    /// Identity.
    pub fn identity(n: usize) -> Self {
        let mut m = Self::zeros(n, n);
        for i in 0..n {
            m.data[i * n + i] = 1.0;
        }
        m
    }
    /// Entry (i, j).
    #[inline]
    pub fn get(&self, i: usize, j: usize) -> f64 {
        self.data[j * self.rows + i]
    }
    /// Set entry (i, j).
    #[inline]
    pub fn set(&mut self, i: usize, j: usize, v: f64) {
        self.data[j * self.rows + i] = v;
    }
    /// Build from a function of (i, j).
    pub fn from_fn(rows: usize, cols: usize, f: impl Fn(usize, usize) -> f64) -> Self {
        let mut m = Self::zeros(rows, cols);
        for j in 0..cols {
            for i in 0..rows {
                m.data[j * rows + i] = f(i, j);
            }
        }
        m
    }
    /// Transpose.
    pub fn transpose(&self) -> Self {
        Self::from_fn(self.cols, self.rows, |i, j| self.get(j, i))
    }
    /// Matrix product `self * other`.
    pub fn mul(&self, other: &DMat) -> DMat {
        assert_eq!(self.cols, other.rows, "DMat::mul dimension mismatch");
        let mut out = DMat::zeros(self.rows, other.cols);
        for j in 0..other.cols {
            let oc = &mut out.data[j * self.rows..(j + 1) * self.rows];
            for k in 0..self.cols {
                let b = other.data[j * other.rows + k];
                if b == 0.0 {
                    continue;
                }
                let ac = &self.data[k * self.rows..(k + 1) * self.rows];
                for (o, a) in oc.iter_mut().zip(ac) {
                    *o += a * b;
                }
            }
        }
        out
    }
    /// `self + s * other`.
    pub fn add_scaled(&self, other: &DMat, s: f64) -> DMat {
        assert_eq!((self.rows, self.cols), (other.rows, other.cols));
        DMat {
            rows: self.rows,
            cols: self.cols,
            data: self.data.iter().zip(&other.data).map(|(a, b)| a + s * b).collect(),
        }
    }
    /// Multiply all entries by `s`.
    pub fn scale(&self, s: f64) -> DMat {
        DMat { rows: self.rows, cols: self.cols, data: self.data.iter().map(|a| a * s).collect() }
    }
    /// Max-abs-column-sum norm.
    pub fn norm1(&self) -> f64 {
        (0..self.cols)
            .map(|j| self.data[j * self.rows..(j + 1) * self.rows].iter().map(|x| x.abs()).sum::<f64>())
            .fold(0.0, f64::max)
    }
    /// Max absolute entry.
    pub fn max_abs(&self) -> f64 {
        self.data.iter().fold(0.0, |m, x| m.max(x.abs()))
    }

    /// Matrix exponential by scaling and squaring with a degree-18 Taylor polynomial
    /// (‖A/2^s‖₁ ≤ 1/4, truncation error below 1e-25 relative).
    pub fn expm(&self) -> DMat {
        assert_eq!(self.rows, self.cols, "expm of a non-square matrix");
        let n = self.rows;
        let norm = self.norm1();
        let s = if norm > 0.25 { (norm / 0.25).log2().ceil() as i32 } else { 0 };
        let a = self.scale(0.5f64.powi(s));
        let mut result = DMat::identity(n);
        let mut term = DMat::identity(n);
        for k in 1..=18 {
            term = term.mul(&a).scale(1.0 / k as f64);
            result = result.add_scaled(&term, 1.0);
        }
        for _ in 0..s {
            result = result.mul(&result);
        }
        result
    }
}

/// Options of the least-squares solves (`Θ = Y Ω†`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LstsqOptions {
    /// Singular values below `rel_tol · σ_max` are truncated.
    pub rel_tol: f64,
    /// Keep at most this many singular values (truncated SVD rank), if set.
    pub max_rank: Option<usize>,
    /// Tikhonov parameter λ ≥ 0: filter factors `σ / (σ² + λ)` instead of `1/σ`.
    pub ridge: f64,
}

impl Default for LstsqOptions {
    fn default() -> Self {
        LstsqOptions { rel_tol: 1e-12, max_rank: None, ridge: 0.0 }
    }
}

/// Solve `M X ≈ Y` in the least-squares sense (`M`: N×d, `Y`: N×q, result d×q) with a
/// (truncated, optionally Tikhonov-filtered) thin SVD of `M` computed by faer.
/// Returns `(X, rank)`.
pub fn lstsq(m: &DMat, y: &DMat, opts: &LstsqOptions) -> Result<(DMat, usize), FitError> {
    if m.rows != y.rows {
        return Err(FitError::Dim(format!("lstsq: M has {} rows, Y has {}", m.rows, y.rows)));
    }
    if m.data.iter().any(|x| !x.is_finite()) {
        return Err(FitError::NonFinite("regressor matrix"));
    }
    if y.data.iter().any(|x| !x.is_finite()) {
        return Err(FitError::NonFinite("target matrix"));
    }
    let (nr, d) = (m.rows, m.cols);
    let fm = faer::Mat::<f64>::from_fn(nr, d, |i, j| m.get(i, j));
    let svd = fm.thin_svd().map_err(|_| FitError::Svd)?;
    let (u, s, v) = (svd.U(), svd.S().column_vector(), svd.V());
    let k = s.nrows();
    let smax = if k > 0 { s[0] } else { 0.0 };
    let mut rank = 0;
    let mut filt = vec![0.0; k];
    for i in 0..k {
        let si = s[i];
        if si > opts.rel_tol * smax && si > 0.0 && opts.max_rank.is_none_or(|r| i < r) {
            filt[i] = si / (si * si + opts.ridge);
            rank += 1;
        }
    }
    // X = V diag(filt) Uᵀ Y
    let q = y.cols;
    let mut uty = DMat::zeros(k, q);
    for c in 0..q {
        let ycol = &y.data[c * nr..(c + 1) * nr];
        for i in 0..k {
            if filt[i] == 0.0 {
                continue;
            }
            let mut acc = 0.0;
            for (r, yv) in ycol.iter().enumerate() {
                acc += u[(r, i)] * yv;
            }
            uty.set(i, c, acc * filt[i]);
        }
    }
    let vm = DMat::from_fn(d, k, |i, j| v[(i, j)]);
    Ok((vm.mul(&uty), rank))
}

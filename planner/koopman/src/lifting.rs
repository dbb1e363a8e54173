//! Dictionaries (liftings) `φ: ℝⁿ → ℝᵖ`.
//!
//! Convention (all liftings in this crate, and required of future ones): the first `n` entries
//! of `φ(x)` are `x` itself, so the decoder `Π = [I 0]` is trivial, as in the paper's
//! `φ(x) = [x, NN(x)]`. [`Lifting::lift`] must not allocate: it is called in the forecast loop
//! (relift mode). A learned lifting (e.g. an MLP with weights in fixed arrays) plugs in by
//! implementing this trait; [`Lifting::lift_derivative`] has a finite-difference default so it
//! only needs `lift`.

/// `dst.copy_from_slice(src)` without a `memcpy` call for the small sizes of the hot loops
/// (constant lengths are copied inline).
#[inline(always)]
pub(crate) fn copy_small(dst: &mut [f64], src: &[f64]) {
    match src.len() {
        6 => dst[..6].copy_from_slice(&src[..6]),
        7 => dst[..7].copy_from_slice(&src[..7]),
        8 => dst[..8].copy_from_slice(&src[..8]),
        n => dst[..n].copy_from_slice(src),
    }
}

/// A dictionary of observables whose first `state_dim()` outputs are the state itself.
pub trait Lifting: Send + Sync {
    /// State dimension `n`.
    fn state_dim(&self) -> usize;
    /// Lifted dimension `p ≥ n`.
    fn dim(&self) -> usize;
    /// `out[..p] = φ(x)`; `x.len() ≥ n`, `out.len() ≥ p`. Must not allocate.
    fn lift(&self, x: &[f64], out: &mut [f64]);
    /// Time derivative of the observables along a flow: `out = Dφ(x) · ẋ`.
    /// Used to fit the continuous-time generator from collocation data (fitting only).
    /// The default uses central finite differences (allocates two buffers).
    fn lift_derivative(&self, x: &[f64], xdot: &[f64], out: &mut [f64]) {
        let (n, p) = (self.state_dim(), self.dim());
        let scale = x[..n].iter().chain(&xdot[..n]).fold(1e-3f64, |m, v| m.max(v.abs()));
        let vn = xdot[..n].iter().map(|v| v * v).sum::<f64>().sqrt();
        if vn == 0.0 {
            out[..p].iter_mut().for_each(|o| *o = 0.0);
            return;
        }
        let h = 1e-5 * scale / vn;
        let mut xp: Vec<f64> = x[..n].iter().zip(xdot).map(|(a, b)| a + h * b).collect();
        let mut fp = vec![0.0; p];
        self.lift(&xp, &mut fp);
        xp.iter_mut().zip(x.iter().zip(xdot)).for_each(|(o, (a, b))| *o = a - h * b);
        self.lift(&xp, &mut out[..p]);
        for i in 0..p {
            out[i] = (fp[i] - out[i]) / (2.0 * h);
        }
    }
}

/// Polynomial dictionary: `[x, 1, all monomials of total degree 2..=d in (x_i / s_i)]`.
/// Degree 1 gives `[x, 1]` (DMD with an affine term).
#[derive(Debug, Clone, PartialEq)]
pub struct Polynomial {
    n: usize,
    degree: usize,
    inv_scale: Vec<f64>,
    /// Flattened variable-index lists of the monomials (each of length = its degree).
    idx: Vec<u16>,
    /// Offsets into `idx`, one more than the number of monomials.
    off: Vec<u32>,
    /// Fast evaluation: monomial `m` = `left(m) · x[b]/s[b]` where `left` is the scaled
    /// variable `a` if `a < n`, else the already computed lifted entry `out[a]`.
    chain: Vec<(u32, u16)>,
    /// Fast path when every monomial has degree 2 and `n ≤ 32`: the variable pairs.
    pairs: Vec<[u16; 2]>,
}

impl Polynomial {
    /// All monomials up to `degree` over `n` variables (unit scales).
    pub fn new(n: usize, degree: usize) -> Self {
        assert!(n >= 1 && n < u16::MAX as usize, "Polynomial: bad state dimension");
        fn gen(
            n: usize,
            left: usize,
            start: usize,
            cur: &mut Vec<u16>,
            idx: &mut Vec<u16>,
            off: &mut Vec<u32>,
        ) {
            if left == 0 {
                idx.extend_from_slice(cur);
                off.push(idx.len() as u32);
                return;
            }
            for i in start..n {
                cur.push(i as u16);
                gen(n, left - 1, i, cur, idx, off);
                cur.pop();
            }
        }
        let mut idx = Vec::new();
        let mut off = vec![0u32];
        for deg in 2..=degree {
            gen(n, deg, 0, &mut Vec::with_capacity(deg), &mut idx, &mut off);
        }
        let chain = Self::build_chain(n, &idx, &off);
        let pairs = Self::build_pairs(n, &idx, &off);
        Polynomial { n, degree, inv_scale: vec![1.0; n], idx, off, chain, pairs }
    }

    /// A sparse polynomial dictionary `[x, 1, selected monomials]`; each monomial is a list of
    /// variable indices (repeats = powers), degree ≥ 2.
    pub fn from_monomials(n: usize, monomials: &[Vec<usize>]) -> Self {
        assert!(n >= 1 && n < u16::MAX as usize, "Polynomial: bad state dimension");
        let mut idx = Vec::new();
        let mut off = vec![0u32];
        let mut degree = 1;
        for m in monomials {
            assert!(m.len() >= 2 && m.iter().all(|&i| i < n), "Polynomial: bad monomial {m:?}");
            let mut v = m.clone();
            v.sort_unstable();
            idx.extend(v.iter().map(|&i| i as u16));
            off.push(idx.len() as u32);
            degree = degree.max(m.len());
        }
        let chain = Self::build_chain(n, &idx, &off);
        let pairs = Self::build_pairs(n, &idx, &off);
        Polynomial { n, degree, inv_scale: vec![1.0; n], idx, off, chain, pairs }
    }

    fn build_pairs(n: usize, idx: &[u16], off: &[u32]) -> Vec<[u16; 2]> {
        if n > 32 || off.windows(2).any(|w| w[1] - w[0] != 2) {
            return Vec::new();
        }
        idx.chunks_exact(2).map(|c| [c[0], c[1]]).collect()
    }

    fn build_chain(n: usize, idx: &[u16], off: &[u32]) -> Vec<(u32, u16)> {
        let mut index = std::collections::HashMap::new();
        let mut chain = Vec::with_capacity(off.len() - 1);
        for m in 0..off.len() - 1 {
            let vars = &idx[off[m] as usize..off[m + 1] as usize];
            let (head, last) = vars.split_at(vars.len() - 1);
            let a = if head.len() == 1 {
                head[0] as u32
            } else {
                // Prefix monomial computed earlier, or generic evaluation (u32::MAX).
                index.get(head).map_or(u32::MAX, |&k: &usize| (n + 1 + k) as u32)
            };
            index.insert(vars.to_vec(), m);
            chain.push((a, last[0]));
        }
        chain
    }
    /// Monomials use `x_i / scale_i` (conditioning); the leading `x` block is unscaled.
    pub fn with_scale(mut self, scale: &[f64]) -> Self {
        assert_eq!(scale.len(), self.n);
        self.inv_scale = scale.iter().map(|s| 1.0 / s).collect();
        self
    }
    /// Polynomial degree.
    pub fn degree(&self) -> usize {
        self.degree
    }
    /// Number of monomials of degree ≥ 2.
    pub fn n_monomials(&self) -> usize {
        self.off.len() - 1
    }
}

impl Lifting for Polynomial {
    fn state_dim(&self) -> usize {
        self.n
    }
    fn dim(&self) -> usize {
        self.n + 1 + self.n_monomials()
    }
    fn lift(&self, x: &[f64], out: &mut [f64]) {
        let n = self.n;
        copy_small(&mut out[..n], &x[..n]);
        out[n] = 1.0;
        let s = &self.inv_scale;
        if !self.pairs.is_empty() {
            // Same products as the chain below (bit-identical), without its branches.
            let mut xs = [0.0; 32];
            for i in 0..n {
                xs[i] = x[i] * s[i];
            }
            for (o, &[a, b]) in out[n + 1..n + 1 + self.pairs.len()].iter_mut().zip(&self.pairs) {
                *o = xs[a as usize] * xs[b as usize];
            }
            return;
        }
        for (m, &(a, b)) in self.chain.iter().enumerate() {
            let (a, b) = (a as usize, b as usize);
            let left = if a < n {
                x[a] * s[a]
            } else if a != u32::MAX as usize {
                out[a]
            } else {
                let vars = &self.idx[self.off[m] as usize..self.off[m + 1] as usize - 1];
                vars.iter().map(|&i| x[i as usize] * s[i as usize]).product()
            };
            out[n + 1 + m] = left * (x[b] * s[b]);
        }
    }
    fn lift_derivative(&self, x: &[f64], xdot: &[f64], out: &mut [f64]) {
        let n = self.n;
        out[..n].copy_from_slice(&xdot[..n]);
        out[n] = 0.0;
        for m in 0..self.off.len() - 1 {
            let vars = &self.idx[self.off[m] as usize..self.off[m + 1] as usize];
            let mut acc = 0.0;
            for k in 0..vars.len() {
                let mut term = xdot[vars[k] as usize] * self.inv_scale[vars[k] as usize];
                for (j, &i) in vars.iter().enumerate() {
                    if j != k {
                        term *= x[i as usize] * self.inv_scale[i as usize];
                    }
                }
                acc += term;
            }
            out[n + 1 + m] = acc;
        }
    }
}

/// Radial basis function kind.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RbfKind {
    /// `exp(−r² / (2σ²))`.
    Gaussian {
        /// Width σ (in scaled units).
        sigma: f64,
    },
    /// Thin-plate spline `r² ln r`.
    ThinPlate,
}

/// RBF dictionary: `[x, 1, ψ(‖(x − c_k) ⊘ s‖) for each centre c_k]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Rbf {
    n: usize,
    kind: RbfKind,
    centres: Vec<f64>,
    inv_scale: Vec<f64>,
    /// Scaled centres, coordinate-major: `cs[i·K + k] = c_k[i] / s_i` (vectorised lift).
    cs: Vec<f64>,
    /// Number of centres.
    k: usize,
}

/// `eˣ` for `x ≤ 709` (inputs below −708 give ≈ 2.2e-308 instead of a subnormal / 0),
/// within ≈ 2 ulp of `f64::exp`, branch-free so that loops over arrays vectorise:
/// `x = k ln 2 + r` (`|r| ≤ ln2/2`, Cody–Waite split of ln 2), `eʳ` by its degree-13 Taylor
/// polynomial (truncation < 1e-17, Estrin's scheme), `2ᵏ` assembled from the exponent bits.
#[inline(always)]
pub fn exp_fast(x: f64) -> f64 {
    exp_poly::<false>(x)
}

/// Constants of [`exp_fast`] (for vectorised versions that must stay bit-identical to it).
pub mod exp_consts {
    /// 1.5 · 2⁵²: adding and subtracting it rounds to the nearest integer.
    pub const MAGIC: f64 = 6755399441055744.0;
    /// ln 2 split into a high part (exact products with small integers) and the rest.
    pub const LN2_HI: f64 = 6.931_471_803_691_238e-1;
    pub const LN2_LO: f64 = 1.908_214_929_270_587_7e-10;
    /// Taylor coefficients 1/i!, i = 0…13.
    pub const C: [f64; 14] = [
        1.0,
        1.0,
        1.0 / 2.0,
        1.0 / 6.0,
        1.0 / 24.0,
        1.0 / 120.0,
        1.0 / 720.0,
        1.0 / 5040.0,
        1.0 / 40320.0,
        1.0 / 362880.0,
        1.0 / 3628800.0,
        1.0 / 39916800.0,
        1.0 / 479001600.0,
        1.0 / 6227020800.0,
    ];
}

/// [`exp_fast`] with fused multiply-adds in the polynomial when `FMA` (only call with
/// `FMA = true` from code compiled with the `fma` target feature; ≤ 1 ulp apart).
#[inline(always)]
fn exp_poly<const FMA: bool>(x: f64) -> f64 {
    #[inline(always)]
    fn ma<const FMA: bool>(a: f64, b: f64, c: f64) -> f64 {
        if FMA {
            a.mul_add(b, c)
        } else {
            a * b + c
        }
    }
    use exp_consts::{C, LN2_HI, LN2_LO, MAGIC};
    let x = x.clamp(-708.0, 709.0);
    let t = x * std::f64::consts::LOG2_E + MAGIC;
    let k = t - MAGIC;
    let ki = (t.to_bits() as i64).wrapping_sub(MAGIC.to_bits() as i64);
    let r = (x - k * LN2_HI) - k * LN2_LO;
    // eʳ = Σ rⁱ/i!, i ≤ 13, evaluated by Estrin's scheme (short dependency chains).
    let r2 = r * r;
    let r4 = r2 * r2;
    let r8 = r4 * r4;
    let q0 = ma::<FMA>(ma::<FMA>(C[3], r, C[2]), r2, ma::<FMA>(C[1], r, C[0]));
    let q1 = ma::<FMA>(ma::<FMA>(C[7], r, C[6]), r2, ma::<FMA>(C[5], r, C[4]));
    let q2 = ma::<FMA>(ma::<FMA>(C[11], r, C[10]), r2, ma::<FMA>(C[9], r, C[8]));
    let q3 = ma::<FMA>(C[13], r, C[12]);
    let p = ma::<FMA>(ma::<FMA>(q3, r4, q2), r8, ma::<FMA>(q1, r4, q0));
    p * f64::from_bits(((ki + 1023) as u64) << 52)
}

impl Rbf {
    /// `centres` is `k × n` row-major.
    pub fn new(n: usize, centres: Vec<f64>, kind: RbfKind) -> Self {
        assert!(n >= 1 && centres.len().is_multiple_of(n), "Rbf: centres must be k × n");
        let k = centres.len() / n;
        let mut r = Rbf { n, kind, centres, inv_scale: vec![1.0; n], cs: Vec::new(), k };
        r.build_scaled();
        r
    }
    fn build_scaled(&mut self) {
        let (n, k) = (self.n, self.k);
        self.cs = vec![0.0; n * k];
        for (c, cen) in self.centres.chunks_exact(n).enumerate() {
            for i in 0..n {
                self.cs[i * k + c] = cen[i] * self.inv_scale[i];
            }
        }
    }

    /// Per-coordinate scaling of distances.
    pub fn with_scale(mut self, scale: &[f64]) -> Self {
        assert_eq!(scale.len(), self.n);
        self.inv_scale = scale.iter().map(|s| 1.0 / s).collect();
        self.build_scaled();
        self
    }
    /// Number of centres.
    pub fn n_centres(&self) -> usize {
        self.k
    }

    /// Same code compiled for AVX2 + FMA (4-wide vectors; the exponential's polynomial with
    /// fused multiply-adds, ≤ 1 ulp from the portable path).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn lift_avx2(&self, x: &[f64], out: &mut [f64]) {
        self.lift_impl::<true>(x, out)
    }

    #[inline(always)]
    fn lift_impl<const FMA: bool>(&self, x: &[f64], out: &mut [f64]) {
        let (n, kc) = (self.n, self.k);
        copy_small(&mut out[..n], &x[..n]);
        out[n] = 1.0;
        // Squared scaled distances to all centres, coordinate by coordinate (vectorises over
        // the centres), accumulated in place, then ψ over the whole block (vectorises too).
        let r2 = &mut out[n + 1..n + 1 + kc];
        r2.iter_mut().for_each(|v| *v = 0.0);
        for i in 0..n {
            let xi = x[i] * self.inv_scale[i];
            for (v, c) in r2.iter_mut().zip(&self.cs[i * kc..(i + 1) * kc]) {
                let d = xi - c;
                *v += d * d;
            }
        }
        match self.kind {
            RbfKind::Gaussian { sigma } => {
                let g = -1.0 / (2.0 * sigma * sigma);
                r2.iter_mut().for_each(|v| *v = exp_poly::<FMA>(*v * g));
            }
            RbfKind::ThinPlate => {
                r2.iter_mut().for_each(|v| *v = if *v > 0.0 { 0.5 * *v * v.ln() } else { 0.0 })
            }
        }
    }
}

impl Lifting for Rbf {
    fn state_dim(&self) -> usize {
        self.n
    }
    fn dim(&self) -> usize {
        self.n + 1 + self.n_centres()
    }
    fn lift(&self, x: &[f64], out: &mut [f64]) {
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
            // SAFETY: the CPU supports AVX2 and FMA (checked at run time).
            return unsafe { self.lift_avx2(x, out) };
        }
        self.lift_impl::<false>(x, out)
    }
    fn lift_derivative(&self, x: &[f64], xdot: &[f64], out: &mut [f64]) {
        let n = self.n;
        out[..n].copy_from_slice(&xdot[..n]);
        out[n] = 0.0;
        for (k, c) in self.centres.chunks_exact(n).enumerate() {
            let (mut r2, mut dr2) = (0.0, 0.0); // dr2 = d/dt r² / 2
            for i in 0..n {
                let s2 = self.inv_scale[i] * self.inv_scale[i];
                let d = x[i] - c[i];
                r2 += d * d * s2;
                dr2 += d * xdot[i] * s2;
            }
            out[n + 1 + k] = match self.kind {
                RbfKind::Gaussian { sigma } => -dr2 / (sigma * sigma) * (-r2 / (2.0 * sigma * sigma)).exp(),
                RbfKind::ThinPlate => {
                    if r2 > 0.0 {
                        dr2 * (r2.ln() + 1.0)
                    } else {
                        0.0
                    }
                }
            };
        }
    }
}

/// Fourier dictionary: `[x, 1, sin(k ω_i x_i), cos(k ω_i x_i) for i < n, k = 1..=K]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Fourier {
    n: usize,
    harmonics: usize,
    omega: Vec<f64>,
}

impl Fourier {
    /// `omega[i]` is the base angular frequency for coordinate `i`.
    pub fn new(omega: Vec<f64>, harmonics: usize) -> Self {
        assert!(!omega.is_empty() && harmonics >= 1);
        Fourier { n: omega.len(), harmonics, omega }
    }
}

impl Lifting for Fourier {
    fn state_dim(&self) -> usize {
        self.n
    }
    fn dim(&self) -> usize {
        self.n + 1 + 2 * self.n * self.harmonics
    }
    fn lift(&self, x: &[f64], out: &mut [f64]) {
        let n = self.n;
        out[..n].copy_from_slice(&x[..n]);
        out[n] = 1.0;
        let mut o = n + 1;
        for i in 0..n {
            for k in 1..=self.harmonics {
                let (s, c) = (k as f64 * self.omega[i] * x[i]).sin_cos();
                out[o] = s;
                out[o + 1] = c;
                o += 2;
            }
        }
    }
    fn lift_derivative(&self, x: &[f64], xdot: &[f64], out: &mut [f64]) {
        let n = self.n;
        out[..n].copy_from_slice(&xdot[..n]);
        out[n] = 0.0;
        let mut o = n + 1;
        for i in 0..n {
            for k in 1..=self.harmonics {
                let w = k as f64 * self.omega[i];
                let (s, c) = (w * x[i]).sin_cos();
                out[o] = c * w * xdot[i];
                out[o + 1] = -s * w * xdot[i];
                o += 2;
            }
        }
    }
}

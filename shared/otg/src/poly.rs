//! Small fixed-size Laurent polynomials and a bracketing real-root finder,
//! used to solve the profile families' equations in closed form.

// The Laurent polynomials are the reference assembly the tests compare the
// fixed-size family equations against.
#![cfg_attr(not(test), allow(dead_code))]

/// Exponent offset: coefficient `c[k]` multiplies `x^(k - OFF)`.
const OFF: i32 = 4;
pub(crate) const LEN: usize = 11;

/// A Laurent polynomial `Σ c_e x^e` with exponents in `-4..=6` (enough for
/// every family: cubes of phase durations that are at most quadratic in, or
/// have a `1/x` term of, the parameter). Products outside the range are a
/// programming error; they are caught by a debug assertion and dropped.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Lp {
    c: [f64; LEN],
    lo: usize,
    hi: usize, // inclusive index range in use (lo > hi means zero)
}

impl Lp {
    pub const ZERO: Lp = Lp { c: [0.0; LEN], lo: 1, hi: 0 };

    pub fn constant(v: f64) -> Lp {
        Lp::mono(v, 0)
    }

    /// `v · x^e`
    pub fn mono(v: f64, e: i32) -> Lp {
        let mut l = Lp::ZERO;
        let k = (e + OFF) as usize;
        l.c[k] = v;
        l.lo = k;
        l.hi = k;
        l
    }

    fn is_zero(&self) -> bool {
        self.lo > self.hi
    }

    pub fn add(&self, o: &Lp) -> Lp {
        if self.is_zero() {
            return *o;
        }
        if o.is_zero() {
            return *self;
        }
        let mut r = *self;
        for k in o.lo..=o.hi {
            r.c[k] += o.c[k];
        }
        r.lo = self.lo.min(o.lo);
        r.hi = self.hi.max(o.hi);
        r
    }

    pub fn scale(&self, s: f64) -> Lp {
        let mut r = *self;
        for k in r.lo..=r.hi.min(LEN - 1) {
            r.c[k] *= s;
        }
        r
    }

    pub fn add_const(&self, s: f64) -> Lp {
        self.add(&Lp::constant(s))
    }

    pub fn mul(&self, o: &Lp) -> Lp {
        if self.is_zero() || o.is_zero() {
            return Lp::ZERO;
        }
        let mut r = Lp::ZERO;
        let off = OFF as usize;
        debug_assert!(self.lo + o.lo >= off && self.hi + o.hi - off < LEN);
        if self.lo + o.lo < off {
            return Lp::ZERO;
        }
        r.lo = self.lo + o.lo - off;
        r.hi = (self.hi + o.hi - off).min(LEN - 1);
        for i in self.lo..=self.hi {
            let ci = self.c[i];
            if ci == 0.0 {
                continue;
            }
            for k in o.lo..=o.hi {
                if let Some(slot) = r.c.get_mut(i + k - off) {
                    *slot += ci * o.c[k];
                }
            }
        }
        r
    }

    pub fn eval(&self, x: f64) -> f64 {
        if self.is_zero() {
            return 0.0;
        }
        let mut s = 0.0;
        for k in (self.lo..=self.hi).rev() {
            s = s * x + self.c[k];
        }
        s * x.powi(self.lo as i32 - OFF)
    }

    /// The polynomial `x^(-lowest exponent) · self` as ascending coefficients.
    pub fn to_poly(self, out: &mut [f64; LEN]) -> usize {
        if self.is_zero() {
            return 0;
        }
        let n = self.hi - self.lo + 1;
        out[..n].copy_from_slice(&self.c[self.lo..=self.hi]);
        n
    }
}

pub(crate) const MAX_ROOTS: usize = 16;

#[inline]
fn horner(c: &[f64], x: f64) -> f64 {
    let mut s = 0.0;
    for &ck in c.iter().rev() {
        s = s * x + ck;
    }
    s
}

/// Real roots of the polynomial with ascending coefficients `c` in `[lo, hi]`,
/// written to `out`; returns how many. Roots of even multiplicity (touching
/// zero) are found as critical points with a tiny value.
pub(crate) fn real_roots(c: &[f64], lo: f64, hi: f64, out: &mut [f64; MAX_ROOTS]) -> usize {
    let mut n = c.len();
    while n > 0 && c[n - 1] == 0.0 {
        n -= 1;
    }
    let c = &c[..n];
    let mut cnt = 0;
    let mut push = |x: f64, cnt: &mut usize| {
        if *cnt < MAX_ROOTS && x >= lo && x <= hi && x.is_finite() {
            out[*cnt] = x;
            *cnt += 1;
        }
    };
    match n {
        0 | 1 => return 0,
        2 => {
            push(-c[0] / c[1], &mut cnt);
            return cnt;
        }
        3 => {
            let (a, b, cc) = (c[2], c[1], c[0]);
            let disc = b * b - 4.0 * a * cc;
            if disc < 0.0 {
                // Possibly a double root lost to rounding.
                let x = -b / (2.0 * a);
                if disc > -1e-14 * (b * b + (4.0 * a * cc).abs()) {
                    push(x, &mut cnt);
                }
                return cnt;
            }
            let sq = disc.sqrt();
            let q = -0.5 * (b + if b >= 0.0 { sq } else { -sq });
            if q != 0.0 {
                push(q / a, &mut cnt);
                push(cc / q, &mut cnt);
            } else {
                push(0.0, &mut cnt);
            }
            return cnt;
        }
        _ => {}
    }
    // Budan's theorem: the number of roots in (lo, hi] is the drop in sign
    // variations of the Taylor coefficients from lo to hi, minus an even
    // number. A drop of 0 or 1 decides without the critical points.
    if lo.is_finite() && hi.is_finite() && lo < hi {
        let (vlo, flo) = variations(c, lo);
        let (vhi, fhi) = variations(c, hi);
        // (A count inconsistent with the end values' signs — rounding —
        // falls through to the general method.)
        let change = flo != 0.0 && fhi != 0.0 && (flo < 0.0) != (fhi < 0.0);
        if flo != 0.0 && fhi != 0.0 && vlo >= vhi {
            if vlo == vhi && !change {
                return cnt;
            }
            if vlo - vhi == 1 && change {
                push(bracketed(c, lo, hi, flo), &mut cnt);
                return cnt;
            }
        }
    }
    // Critical points from the derivative.
    let mut d = [0.0f64; LEN];
    for k in 1..n {
        d[k - 1] = c[k] * k as f64;
    }
    let mut crit = [0.0f64; MAX_ROOTS];
    let nc = real_roots(&d[..n - 1], lo, hi, &mut crit);
    let crit = &mut crit[..nc];
    crit.sort_unstable_by(|a, b| a.total_cmp(b));
    let scale = c.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let mut prev = lo;
    let mut fprev = horner(c, lo);
    if fprev == 0.0 {
        push(lo, &mut cnt);
    }
    for i in 0..=nc {
        let x = if i < nc { crit[i] } else { hi };
        let fx = horner(c, x);
        if fprev != 0.0 && fx != 0.0 && (fprev < 0.0) != (fx < 0.0) {
            push(bracketed(c, prev, x, fprev), &mut cnt);
        } else if fx == 0.0 {
            push(x, &mut cnt);
        } else if i < nc {
            // Touching root at a critical point?
            let xs = x.abs().max(1.0);
            if fx.abs() <= 1e-13 * scale * xs.powi(n as i32 - 1) {
                push(x, &mut cnt);
            }
        }
        prev = x;
        fprev = fx;
    }
    cnt
}

/// Sign variations of the Taylor coefficients of `c` at `x` (zeros
/// skipped), and the value `c(x)`.
#[inline]
fn variations(c: &[f64], x: f64) -> (u32, f64) {
    match c.len() {
        4 => variations_n::<4>(c, x),
        5 => variations_n::<5>(c, x),
        6 => variations_n::<6>(c, x),
        7 => variations_n::<7>(c, x),
        _ => variations_slow(c, x),
    }
}

#[inline(always)]
fn variations_n<const M: usize>(c: &[f64], x: f64) -> (u32, f64) {
    let mut b = [0.0f64; M];
    b.copy_from_slice(&c[..M]);
    for i in 0..M - 1 {
        for k in (i..M - 1).rev() {
            b[k] += x * b[k + 1];
        }
    }
    let mut v = 0;
    let mut zero = false;
    for k in 0..M - 1 {
        v += ((b[k].to_bits() ^ b[k + 1].to_bits()) >> 63) as u32;
        zero |= b[k] == 0.0;
    }
    if zero || b[M - 1] == 0.0 {
        return variations_slow(c, x);
    }
    (v, b[0])
}

fn variations_slow(c: &[f64], x: f64) -> (u32, f64) {
    let n = c.len();
    let mut b = [0.0f64; LEN];
    b[..n].copy_from_slice(c);
    for i in 0..n - 1 {
        for k in (i..n - 1).rev() {
            b[k] += x * b[k + 1];
        }
    }
    let mut v = 0;
    let mut prev = 0.0f64;
    for &bk in &b[..n] {
        if bk != 0.0 {
            if prev != 0.0 && (prev < 0.0) != (bk < 0.0) {
                v += 1;
            }
            prev = bk;
        }
    }
    (v, b[0])
}

/// Root in `[a, b]` where the sign changes: Newton steps safeguarded by
/// bisection, stopping once the residual is at rounding-noise level.
fn bracketed(c: &[f64], mut a: f64, mut b: f64, fa: f64) -> f64 {
    let neg_a = fa < 0.0;
    // Start from the secant point (usually much closer than the midpoint).
    let fb = horner(c, b);
    let mut x = if fb != fa { a - fa * (b - a) / (fb - fa) } else { 0.5 * (a + b) };
    if !(x > a && x < b) {
        x = 0.5 * (a + b);
    }
    for _ in 0..64 {
        let (mut f, mut df, mut d2, mut m) = (0.0, 0.0, 0.0, 0.0);
        let ax = x.abs();
        for &ck in c.iter().rev() {
            d2 = d2 * x + df;
            df = df * x + f;
            f = f * x + ck;
            m = m * ax + ck.abs();
        }
        if f.abs() <= 4.0 * f64::EPSILON * m {
            return x;
        }
        if (f < 0.0) == neg_a {
            a = x;
        } else {
            b = x;
        }
        // Halley step (f''/2 = d2).
        let xn = x - f * df / (df * df - f * d2);
        let next = if df != 0.0 && xn > a && xn < b { xn } else { 0.5 * (a + b) };
        if (next - x).abs() <= 2.0 * f64::EPSILON * x.abs()
            || b - a <= 2.0 * f64::EPSILON * a.abs().max(b.abs())
        {
            return next;
        }
        x = next;
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roots_of_known_polynomials() {
        let mut out = [0.0; MAX_ROOTS];
        // (x-1)(x-2)(x-3)(x+0.5) = x^4 - 5.5x^3 + 8x^2 - 0.5x - 3
        let c = [-3.0, -0.5, 8.0, -5.5, 1.0];
        let n = real_roots(&c, -10.0, 10.0, &mut out);

        let mut r = out[..n].to_vec();
        r.sort_by(|a, b| a.total_cmp(b));
        assert_eq!(n, 4);
        for (x, e) in r.iter().zip([-0.5, 1.0, 2.0, 3.0]) {
            assert!((x - e).abs() < 1e-12, "{r:?}");
        }
        // Double root: (x-1)^2 (x+2) = x^3 - 3x + 2
        let n = real_roots(&[2.0, -3.0, 0.0, 1.0], -5.0, 5.0, &mut out);
        assert!(out[..n].iter().any(|x| (x - 1.0).abs() < 1e-7));
        assert!(out[..n].iter().any(|x| (x + 2.0).abs() < 1e-12));
    }

    #[test]
    fn laurent_arithmetic() {
        let x = Lp::mono(1.0, 1);
        let inv = Lp::mono(2.0, -1);
        let p = x.add(&inv).mul(&x.add(&inv)); // x² + 4 + 4/x²
        assert!((p.eval(2.0) - (4.0 + 4.0 + 1.0)).abs() < 1e-12);
    }
}

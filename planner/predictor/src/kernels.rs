//! Dense kernels of the roll-out [`crate::models::Engine`]: a portable version of each and an
//! AVX2 version with explicit 4-wide intrinsics performing the same IEEE operations in the
//! same order (separate multiplies and adds, never FMA), so both give bit-identical results.
//! The AVX2 versions are only called from code compiled with the `avx2` target feature after
//! a run-time check.

use dkrrt_deep::DeepLifting;
use dkrrt_koopman::{exp_fast, Lifting};

/// Padded row count of the state-row kernels (translation n = 6, attitude n = 7).
pub(crate) const ROWS: usize = 8;

/// `Σ_j cols[j] · z[j]` over `p = z.len()` state-row columns of [`ROWS`] entries: four
/// accumulator sets (columns `j ≡ 0, 1, 2, 3 mod 4`, short dependency chains), summed as
/// `(a0 + a1) + (a2 + a3)`.
#[inline(always)]
pub(crate) fn state_rows(cols: &[f64], z: &[f64]) -> [f64; ROWS] {
    let mut acc = [[0.0; ROWS]; 4];
    let p = z.len();
    let cols = &cols[..p * ROWS];
    for (j, (col, &zj)) in cols.chunks_exact(ROWS).zip(z).enumerate() {
        let a = &mut acc[j % 4];
        for i in 0..ROWS {
            a[i] += col[i] * zj;
        }
    }
    let mut r = [0.0; ROWS];
    for i in 0..ROWS {
        r[i] = (acc[0][i] + acc[1][i]) + (acc[2][i] + acc[3][i]);
    }
    r
}

/// `out[..4B] = A z`, `A` = `p` columns of `4B` entries (column-major, padded), sums over `j`
/// in order; returns `out[..8]` (`B ≥ 2`).
#[inline(always)]
pub(crate) fn lifted<const B: usize>(a: &[f64], z: &[f64], out: &mut [f64]) -> [f64; ROWS] {
    let pp = 4 * B;
    let p = z.len();
    let mut acc = [[0.0; 4]; B];
    for (col, &zj) in a[..p * pp].chunks_exact(pp).zip(z) {
        for b in 0..B {
            for l in 0..4 {
                acc[b][l] += col[4 * b + l] * zj;
            }
        }
    }
    for (o, a) in out[..pp].chunks_exact_mut(4).zip(&acc) {
        o.copy_from_slice(a);
    }
    let mut head = [0.0; ROWS];
    head[..4].copy_from_slice(&acc[0]);
    head[4..].copy_from_slice(&acc[1]);
    head
}

/// Gaussians of 4 RBF centres: [`exp_fast`]`(g · Σ_i (xs_i − c_{i,l})²)` (sum over `i` in
/// order from 0, as the reference lift), `blk[4i + l]` = scaled coordinate `i` of centre `l`.
#[inline(always)]
pub(crate) fn rbf_block(xs: &[f64; 7], blk: &[f64; 28], g: f64) -> [f64; 4] {
    let mut r2 = [0.0; 4];
    for i in 0..7 {
        for l in 0..4 {
            let d = xs[i] - blk[i * 4 + l];
            r2[l] += d * d;
        }
    }
    let mut e = [0.0; 4];
    for l in 0..4 {
        e[l] = exp_fast(r2[l] * g);
    }
    e
}

/// [`DeepLifting::lift`] (`φ(x) = [x, NN(x)]`): `dkrrt-deep`'s own code, inlined
/// (`DeepLifting::features` is `#[inline(always)]`) so that [`avx2::deep_lift`] compiles it for
/// AVX2 — the same operations in the same order, bit-identical.
#[inline(always)]
pub(crate) fn deep_lift(l: &DeepLifting, x: &[f64], out: &mut [f64]) {
    let (n, extra) = (l.state_dim(), l.extra());
    out[..n].copy_from_slice(&x[..n]);
    l.features(x, &mut out[n..n + extra]);
}

#[cfg(target_arch = "x86_64")]
pub(crate) mod avx2 {
    //! AVX2 versions (see the module documentation of the parent).

    use super::ROWS;
    use std::arch::x86_64::*;

    /// [`super::deep_lift`] compiled for AVX2.
    #[target_feature(enable = "avx2")]
    #[inline(never)]
    pub(crate) unsafe fn deep_lift(l: &super::DeepLifting, x: &[f64], out: &mut [f64]) {
        super::deep_lift(l, x, out)
    }

    /// [`super::state_rows`].
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(crate) unsafe fn state_rows(cols: &[f64], z: &[f64]) -> [f64; ROWS] {
        let p = z.len();
        let cols = &cols[..p * ROWS];
        let c = cols.as_ptr();
        let mut a = [_mm256_setzero_pd(); 8];
        let full = p / 4;
        for q in 0..full {
            for s in 0..4 {
                let j = 4 * q + s;
                // SAFETY: j < p; column j spans cols[j·8 .. j·8 + 8].
                let zv = _mm256_set1_pd(*z.get_unchecked(j));
                let col = c.add(j * ROWS);
                a[2 * s] = _mm256_add_pd(a[2 * s], _mm256_mul_pd(_mm256_loadu_pd(col), zv));
                a[2 * s + 1] = _mm256_add_pd(a[2 * s + 1], _mm256_mul_pd(_mm256_loadu_pd(col.add(4)), zv));
            }
        }
        for s in 0..p % 4 {
            let j = 4 * full + s;
            // SAFETY: as above.
            let zv = _mm256_set1_pd(*z.get_unchecked(j));
            let col = c.add(j * ROWS);
            a[2 * s] = _mm256_add_pd(a[2 * s], _mm256_mul_pd(_mm256_loadu_pd(col), zv));
            a[2 * s + 1] = _mm256_add_pd(a[2 * s + 1], _mm256_mul_pd(_mm256_loadu_pd(col.add(4)), zv));
        }
        let lo = _mm256_add_pd(_mm256_add_pd(a[0], a[2]), _mm256_add_pd(a[4], a[6]));
        let hi = _mm256_add_pd(_mm256_add_pd(a[1], a[3]), _mm256_add_pd(a[5], a[7]));
        let mut r = [0.0; ROWS];
        _mm256_storeu_pd(r.as_mut_ptr(), lo);
        _mm256_storeu_pd(r.as_mut_ptr().add(4), hi);
        r
    }

    /// [`super::lifted`].
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(crate) unsafe fn lifted<const B: usize>(a: &[f64], z: &[f64], out: &mut [f64]) -> [f64; ROWS] {
        let pp = 4 * B;
        let p = z.len();
        let (a, out) = (&a[..p * pp], &mut out[..pp]);
        let mut acc = [_mm256_setzero_pd(); B];
        for (col, &zj) in a.chunks_exact(pp).zip(z) {
            let zv = _mm256_set1_pd(zj);
            for b in 0..B {
                // SAFETY: `col` has 4·B entries.
                acc[b] = _mm256_add_pd(acc[b], _mm256_mul_pd(_mm256_loadu_pd(col.as_ptr().add(4 * b)), zv));
            }
        }
        for b in 0..B {
            // SAFETY: `out` has 4·B entries.
            _mm256_storeu_pd(out.as_mut_ptr().add(4 * b), acc[b]);
        }
        let mut head = [0.0; ROWS];
        _mm256_storeu_pd(head.as_mut_ptr(), acc[0]);
        _mm256_storeu_pd(head.as_mut_ptr().add(4), acc[1]);
        head
    }

    /// [`super::rbf_block`] for `W` coordinate vectors (lanes) against the same 4 centres, the
    /// statements of the lanes interleaved: independent dependency chains side by side (the
    /// exponential is latency-bound otherwise; this is ≈ 20 % of the RBF forecast).
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(crate) unsafe fn rbf_lanes<const W: usize>(
        xs: &[[f64; 7]; W],
        blk: &[f64; 28],
        g: f64,
    ) -> [__m256d; W] {
        let mut r2 = [_mm256_setzero_pd(); W];
        for i in 0..7 {
            // SAFETY: blk has 28 entries.
            let c = _mm256_loadu_pd(blk.as_ptr().add(4 * i));
            for w in 0..W {
                let d = _mm256_sub_pd(_mm256_broadcast_sd(&xs[w][i]), c);
                r2[w] = _mm256_add_pd(r2[w], _mm256_mul_pd(d, d));
            }
        }
        let gv = _mm256_set1_pd(g);
        exp4w(r2.map(|v| _mm256_mul_pd(v, gv)))
    }

    /// `W × 4` × [`dkrrt_koopman::exp_fast`]: the same operations (separate multiplies and
    /// adds: bit-identical, NaN passes), the statements of the `W` vectors interleaved.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(crate) unsafe fn exp4w<const W: usize>(x: [__m256d; W]) -> [__m256d; W] {
        use dkrrt_koopman::exp_consts::{C, LN2_HI, LN2_LO, MAGIC};
        let s = _mm256_set1_pd;
        let (add, sub, mul) = (_mm256_add_pd, _mm256_sub_pd, _mm256_mul_pd);
        let ma = |a, b, c| add(mul(a, b), c);
        // f64::clamp(−708, 709): max/min return their second operand when it is NaN.
        let x = x.map(|x| _mm256_min_pd(s(709.0), _mm256_max_pd(s(-708.0), x)));
        let m = s(MAGIC);
        let t = x.map(|x| add(mul(x, s(std::f64::consts::LOG2_E)), m));
        let k = t.map(|t| sub(t, m));
        let ki =
            t.map(|t| _mm256_sub_epi64(_mm256_castpd_si256(t), _mm256_set1_epi64x(MAGIC.to_bits() as i64)));
        let mut r = x;
        for w in 0..W {
            r[w] = sub(sub(x[w], mul(k[w], s(LN2_HI))), mul(k[w], s(LN2_LO)));
        }
        let r2 = r.map(|r| mul(r, r));
        let r4 = r2.map(|r| mul(r, r));
        let r8 = r4.map(|r| mul(r, r));
        let mut out = x;
        for w in 0..W {
            let (r, r2, r4, r8) = (r[w], r2[w], r4[w], r8[w]);
            let q0 = ma(ma(s(C[3]), r, s(C[2])), r2, ma(s(C[1]), r, s(C[0])));
            let q1 = ma(ma(s(C[7]), r, s(C[6])), r2, ma(s(C[5]), r, s(C[4])));
            let q2 = ma(ma(s(C[11]), r, s(C[10])), r2, ma(s(C[9]), r, s(C[8])));
            let q3 = ma(s(C[13]), r, s(C[12]));
            let p = ma(ma(q3, r4, q2), r8, ma(q1, r4, q0));
            let e = _mm256_slli_epi64::<52>(_mm256_add_epi64(ki[w], _mm256_set1_epi64x(1023)));
            out[w] = mul(p, _mm256_castsi256_pd(e));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn exp4w_equals_exp_fast_bitwise() {
        if !std::is_x86_feature_detected!("avx2") {
            return;
        }
        use std::arch::x86_64::*;
        let mut rng = SmallRng::seed_from_u64(3);
        let mut xs: Vec<f64> = vec![
            0.0,
            -0.0,
            1.0,
            -1.0,
            -708.0,
            -709.5,
            709.0,
            710.0,
            -1e300,
            1e300,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            f64::MIN_POSITIVE,
        ];
        xs.extend((0..40000).map(|_| rng.random_range(-750.0..750.0)));
        xs.extend((0..40000).map(|_| rng.random_range(-40.0..1.0)));
        xs.resize(xs.len().next_multiple_of(8), 0.5);
        for c in xs.chunks_exact(8) {
            let mut got = [0.0; 8];
            // SAFETY: AVX2 checked above.
            unsafe {
                let e = avx2::exp4w([_mm256_loadu_pd(c.as_ptr()), _mm256_loadu_pd(c.as_ptr().add(4))]);
                _mm256_storeu_pd(got.as_mut_ptr(), e[0]);
                _mm256_storeu_pd(got.as_mut_ptr().add(4), e[1]);
            }
            for l in 0..8 {
                let want = exp_fast(c[l]);
                assert!(
                    got[l].to_bits() == want.to_bits() || (got[l].is_nan() && want.is_nan()),
                    "exp4w({}) = {:e}, exp_fast = {:e}",
                    c[l],
                    got[l],
                    want
                );
            }
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_kernels_equal_portable_bitwise() {
        if !std::is_x86_feature_detected!("avx2") {
            return;
        }
        use std::arch::x86_64::*;
        let mut rng = SmallRng::seed_from_u64(5);
        let mut v = |n: usize| -> Vec<f64> { (0..n).map(|_| rng.random_range(-2.0..2.0)).collect() };
        for p in 1..=40 {
            let (cols, z) = (v(p * ROWS), v(p));
            // SAFETY: AVX2 checked above.
            let got = unsafe { avx2::state_rows(&cols, &z) };
            assert_eq!(got.map(f64::to_bits), state_rows(&cols, &z).map(f64::to_bits), "state_rows p = {p}");
            let (a, mut o1, mut o2) = (v(p * 24), vec![0.0; 24], vec![0.0; 24]);
            let h1 = lifted::<6>(&a, &z, &mut o1);
            // SAFETY: as above.
            let h2 = unsafe { avx2::lifted::<6>(&a, &z, &mut o2) };
            assert_eq!(o1, o2, "lifted p = {p}");
            assert_eq!(h1, h2, "lifted p = {p}");
            assert_eq!(h1[..], o1[..8], "lifted p = {p}");
        }
        for _ in 0..1000 {
            let blk: [f64; 28] = v(28).try_into().unwrap();
            let xs: [[f64; 7]; 3] = std::array::from_fn(|_| v(7).try_into().unwrap());
            let g = -1.0 / (2.0 * 1.5 * 1.5);
            // SAFETY: as above.
            let es = unsafe { avx2::rbf_lanes::<3>(&xs, &blk, g) };
            for (x, e) in xs.iter().zip(es) {
                let mut got = [0.0; 4];
                // SAFETY: as above.
                unsafe { _mm256_storeu_pd(got.as_mut_ptr(), e) };
                assert_eq!(got.map(f64::to_bits), rbf_block(x, &blk, g).map(f64::to_bits));
            }
        }
    }

    #[test]
    fn deep_lift_equals_reference_bitwise() {
        let mut rng = SmallRng::seed_from_u64(9);
        for (n, hidden, layers, extra) in [(7, 32, 2, 16), (7, 8, 1, 5), (5, 13, 3, 3)] {
            let np = dkrrt_deep::lifting::param_count(n, hidden, layers, extra);
            let params: Vec<f64> = (0..np).map(|_| rng.random_range(-1.0..1.0)).collect();
            let offset: Vec<f64> = (0..n).map(|_| rng.random_range(-0.5..0.5)).collect();
            let scale: Vec<f64> = (0..n).map(|_| rng.random_range(0.3..3.0)).collect();
            let l = DeepLifting::new(n, hidden, layers, extra, &offset, &scale, &params).unwrap();
            for _ in 0..200 {
                let x: Vec<f64> = (0..n).map(|_| rng.random_range(-3.0..3.0)).collect();
                let (mut want, mut got) = (vec![0.0; n + extra], vec![0.0; n + extra]);
                l.lift(&x, &mut want);
                deep_lift(&l, &x, &mut got);
                assert_eq!(got, want);
                #[cfg(target_arch = "x86_64")]
                if std::is_x86_feature_detected!("avx2") {
                    got.fill(0.0);
                    // SAFETY: AVX2 checked above.
                    unsafe { avx2::deep_lift(&l, &x, &mut got) };
                    assert!(got.iter().zip(&want).all(|(a, b)| a.to_bits() == b.to_bits()));
                }
            }
        }
    }
}

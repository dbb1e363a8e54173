//! Training f_θ with candle (CPU, f32): the paper's Algorithm 1.
//!
//! * Data: sequences of consecutive views of one object by one camera, each view with its
//!   true observables ([`crate::targets`]); a view's previous view is the one before it
//!   in its sequence (the first one's is itself, as at inference when there is none).
//! * Koopman state `z = [f_θ(view, previous view), 1]` (`P` values). Loss on a window
//!   `τ₀ … τ₀ + H`: `L = 1/(H+1) Σₖ mean((C Kᵏ z(τ₀) − y(τ₀ + k))²)`, `C` the first
//!   [`N_OBS`] values: the observables now (k = 0) and predicted ahead.
//! * `K` is re-solved by ridge least squares ([`resolve_koopman`], faer's SVD via
//!   `dkrrt_koopman::linalg::lstsq`) on all consecutive training pairs with the current f_θ
//!   before the first epoch and every `resolve_every` epochs (`M`), and held between (Adam
//!   trains f_θ only); the constant's row of `K` is `e_c`.
//! * The validation sequences (the caller's split: other runs than the training ones) give
//!   the RMSE of the observables per horizon after every epoch; the parameters with the best
//!   validation loss are returned.
//! * Deterministic for a given seed (weights and shuffling from `SmallRng::seed_from_u64`).

use crate::{
    decode, View, VisualNet, C1, C2, C3, CROP, FLAT, HIDDEN, IN_CH, IN_LEN, N_OBS, N_OUT, N_SCALARS, P,
    PARAM_SIZES, VIEW_LEN,
};
use candle_core::{DType, Device, Tensor, Var};
use candle_nn::optim::{AdamW, Optimizer, ParamsAdamW};
use dkrrt_koopman::linalg::{lstsq, DMat, LstsqOptions};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use std::time::Instant;

/// One view of an object with its true observables.
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    pub view: View,
    pub y: [f32; N_OBS],
}

/// Consecutive views of one object by one camera (one capture apart).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Sequence {
    pub samples: Vec<Sample>,
}

/// Training hyper-parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct VisualTrainConfig {
    /// Passes over the training windows.
    pub epochs: usize,
    /// Re-solve `K` every this many epochs (`M` in Algorithm 1, ≥ 1).
    pub resolve_every: usize,
    /// Prediction horizon `H` of the loss, captures.
    pub horizon: usize,
    /// Adam learning rate (cosine decay to 5 %).
    pub lr: f64,
    /// Minibatch size, windows.
    pub batch: usize,
    /// Ridge parameter of the `K` solve per pair.
    pub ridge: f64,
    /// At most this many training windows per epoch (an evenly spread, reshuffled subset).
    pub max_windows: usize,
    pub seed: u64,
}

impl Default for VisualTrainConfig {
    fn default() -> Self {
        VisualTrainConfig {
            epochs: 30,
            resolve_every: 3,
            horizon: 4,
            lr: 2e-3,
            batch: 64,
            ridge: 1e-6,
            max_windows: 12_000,
            seed: 15,
        }
    }
}

/// After each epoch (the deep model's trainer's progress record).
pub use dkrrt_deep::Progress;

/// What training did.
#[derive(Debug, Clone, PartialEq)]
pub struct VisualTrainReport {
    /// Validation loss before the first epoch (the initial f_θ and its least-squares `K`).
    pub initial_valid_loss: f64,
    /// Training loss per epoch (mean over its minibatches).
    pub train_loss: Vec<f64>,
    /// Validation loss per epoch.
    pub valid_loss: Vec<f64>,
    /// Epoch of the returned parameters (0: the initial ones).
    pub best_epoch: usize,
    /// Validation RMSE of the observables per horizon `0..=H` with the returned parameters.
    pub valid_rmse: Vec<f64>,
    /// Median angle between predicted and true axes (now, k = 0) where both are sure, rad:
    /// long axes, short axes.
    pub valid_axis_err_rad: [f64; 2],
    pub train_windows: usize,
    pub valid_windows: usize,
    pub seconds: f64,
}

/// Why training failed.
#[derive(Debug, thiserror::Error)]
pub enum VisualTrainError {
    #[error("visual training data: {0}")]
    Data(String),
    #[error("visual training config: {0}")]
    Config(String),
    #[error("candle: {0}")]
    Candle(#[from] candle_core::Error),
    #[error("koopman least squares: {0}")]
    Fit(#[from] dkrrt_koopman::FitError),
}

/// Flattened samples of a set of sequences.
struct Set {
    views: Vec<f32>,
    scalars: Vec<f32>,
    y: Vec<f32>,
    prev: Vec<u32>,
    /// First samples of windows of `H + 1` views.
    windows: Vec<u32>,
    /// First samples of consecutive pairs.
    pairs: Vec<u32>,
}

impl Set {
    fn new(seqs: &[Sequence], h: usize) -> Result<Set, VisualTrainError> {
        let mut s = Set {
            views: Vec::new(),
            scalars: Vec::new(),
            y: Vec::new(),
            prev: Vec::new(),
            windows: Vec::new(),
            pairs: Vec::new(),
        };
        for (q, seq) in seqs.iter().enumerate() {
            let base = s.prev.len() as u32;
            for (i, smp) in seq.samples.iter().enumerate() {
                let bad = |v: &[f32]| v.iter().any(|x| !x.is_finite());
                if bad(&smp.view.px) || bad(&smp.view.scalars) || bad(&smp.y) {
                    return Err(VisualTrainError::Data(format!(
                        "sequence {q}, sample {i}: non-finite value"
                    )));
                }
                s.views.extend_from_slice(&smp.view.px);
                s.scalars.extend_from_slice(&smp.view.scalars);
                s.y.extend_from_slice(&smp.y);
                let g = base + i as u32;
                s.prev.push(if i == 0 { g } else { g - 1 });
                if i + 1 < seq.samples.len() {
                    s.pairs.push(g);
                }
                if i + h < seq.samples.len() {
                    s.windows.push(g);
                }
            }
        }
        Ok(s)
    }

    fn len(&self) -> usize {
        self.prev.len()
    }

    /// Inputs of samples `idx`: images `(B, IN_CH, CROP, CROP)` and scalars `(B, 3)`.
    fn inputs(&self, idx: &[u32], dev: &Device) -> candle_core::Result<(Tensor, Tensor)> {
        let mut x = Vec::with_capacity(idx.len() * IN_LEN);
        let mut s = Vec::with_capacity(idx.len() * N_SCALARS);
        for &i in idx {
            let (i, p) = (i as usize, self.prev[i as usize] as usize);
            x.extend_from_slice(&self.views[i * VIEW_LEN..(i + 1) * VIEW_LEN]);
            x.extend_from_slice(&self.views[p * VIEW_LEN..(p + 1) * VIEW_LEN]);
            s.extend_from_slice(&self.scalars[i * N_SCALARS..(i + 1) * N_SCALARS]);
        }
        Ok((
            Tensor::from_vec(x, (idx.len(), IN_CH, CROP, CROP), dev)?,
            Tensor::from_vec(s, (idx.len(), N_SCALARS), dev)?,
        ))
    }

    /// Targets of samples `idx + k`: `(B, N_OBS)`.
    fn targets(&self, idx: &[u32], k: usize, dev: &Device) -> candle_core::Result<Tensor> {
        let mut y = Vec::with_capacity(idx.len() * N_OBS);
        for &i in idx {
            let i = i as usize + k;
            y.extend_from_slice(&self.y[i * N_OBS..(i + 1) * N_OBS]);
        }
        Tensor::from_vec(y, (idx.len(), N_OBS), dev)
    }
}

struct Net {
    vars: Vec<Var>,
}

/// Shapes of the parameter tensors as candle holds them, with their fan-in (0: a bias).
fn shapes() -> [(Vec<usize>, usize); 10] {
    [
        (vec![C1, IN_CH, 3, 3], IN_CH * 9),
        (vec![C1], 0),
        (vec![C2, C1, 3, 3], C1 * 9),
        (vec![C2], 0),
        (vec![C3, C2, 3, 3], C2 * 9),
        (vec![C3], 0),
        (vec![FLAT, HIDDEN], FLAT),
        (vec![1, HIDDEN], 0),
        (vec![HIDDEN, N_OUT], HIDDEN),
        (vec![1, N_OUT], 0),
    ]
}

impl Net {
    fn init(rng: &mut SmallRng, dev: &Device) -> candle_core::Result<Net> {
        let mut vars = Vec::new();
        for (shape, fan_in) in shapes() {
            let n: usize = shape.iter().product();
            let v: Vec<f32> = if fan_in == 0 {
                vec![0.0; n]
            } else {
                let a = (6.0 / fan_in as f64).sqrt() as f32;
                (0..n).map(|_| rng.random_range(-a..a)).collect()
            };
            vars.push(Var::from_tensor(&Tensor::from_vec(v, shape, dev)?)?);
        }
        Ok(Net { vars })
    }

    fn from_net(net: &VisualNet, dev: &Device) -> candle_core::Result<Net> {
        let vars = shapes()
            .into_iter()
            .zip(net.params())
            .map(|((shape, _), p)| Var::from_tensor(&Tensor::from_vec(p.to_vec(), shape, dev)?))
            .collect::<candle_core::Result<_>>()?;
        Ok(Net { vars })
    }

    fn forward(&self, x: &Tensor, s: &Tensor) -> candle_core::Result<Tensor> {
        let v = &self.vars;
        let conv = |x: &Tensor, w: &Var, b: &Var, c: usize| -> candle_core::Result<Tensor> {
            x.conv2d(w, 1, 2, 1, 1)?.broadcast_add(&b.reshape((1, c, 1, 1))?)?.relu()
        };
        let a = conv(x, &v[0], &v[1], C1)?;
        let a = conv(&a, &v[2], &v[3], C2)?;
        let a = conv(&a, &v[4], &v[5], C3)?;
        let f = Tensor::cat(&[&a.flatten_from(1)?, s], 1)?;
        let h = f.matmul(&v[6])?.broadcast_add(&v[7])?.relu()?;
        h.matmul(&v[8])?.broadcast_add(&v[9])
    }

    fn params(&self) -> candle_core::Result<Vec<Vec<f32>>> {
        self.vars.iter().map(|v| v.flatten_all()?.to_vec1::<f32>()).collect()
    }

    fn set(&self, params: &[Vec<f32>]) -> candle_core::Result<()> {
        for (v, p) in self.vars.iter().zip(params) {
            v.set(&Tensor::from_vec(p.clone(), v.shape(), v.device())?)?;
        }
        Ok(())
    }

    /// Features of all samples of `set` (row-major `len × N_OUT`), without gradients.
    fn features_all(&self, set: &Set, dev: &Device) -> candle_core::Result<Vec<f64>> {
        let mut out = Vec::with_capacity(set.len() * N_OUT);
        let idx: Vec<u32> = (0..set.len() as u32).collect();
        for chunk in idx.chunks(256) {
            let (x, s) = set.inputs(chunk, dev)?;
            let f = self.forward(&x, &s)?.detach();
            out.extend(f.flatten_all()?.to_vec1::<f32>()?.into_iter().map(|v| v as f64));
        }
        Ok(out)
    }
}

/// `K` (row-major `P × P`, `ξ(t+1) = K [ξ(t); 1]`) by ridge least squares over the pairs
/// `(features[i], features[i+1])` for `i` in `pairs` (`features` row-major, `N_OUT` per
/// sample); the constant's row is `e_c`. Ridge `λ = ridge · pairs`.
pub fn resolve_koopman(features: &[f64], pairs: &[u32], ridge: f64) -> Result<Vec<f64>, VisualTrainError> {
    let np = pairs.len();
    if np < P {
        return Err(VisualTrainError::Data(format!("{np} consecutive pairs are too few for a {P}-state K")));
    }
    let z = |i: usize, j: usize| if j == N_OUT { 1.0 } else { features[i * N_OUT + j] };
    let mut m = DMat::zeros(np, P);
    let mut y = DMat::zeros(np, P);
    for (r, &i) in pairs.iter().enumerate() {
        for j in 0..P {
            m.data[j * np + r] = z(i as usize, j);
            y.data[j * np + r] = z(i as usize + 1, j);
        }
    }
    let opts = LstsqOptions { rel_tol: 1e-12, max_rank: None, ridge: ridge * np as f64 };
    let (kt, _) = lstsq(&m, &y, &opts)?; // P × P = Kᵀ
    let mut k = vec![0.0; P * P];
    for i in 0..P {
        for j in 0..P {
            k[i * P + j] = if i == N_OUT {
                if j == N_OUT {
                    1.0
                } else {
                    0.0
                }
            } else {
                kt.get(j, i)
            };
        }
    }
    Ok(k)
}

fn kt_tensor(k: &[f64], dev: &Device) -> candle_core::Result<Tensor> {
    let mut t = vec![0f32; P * P];
    for i in 0..P {
        for j in 0..P {
            t[j * P + i] = k[i * P + j] as f32;
        }
    }
    Tensor::from_vec(t, (P, P), dev)
}

/// Mean multi-step loss of windows `idx` (and its backward graph).
fn window_loss(
    net: &Net,
    set: &Set,
    idx: &[u32],
    kt: &Tensor,
    h: usize,
    dev: &Device,
) -> candle_core::Result<Tensor> {
    let (x, s) = set.inputs(idx, dev)?;
    let f = net.forward(&x, &s)?;
    let mut z = Tensor::cat(&[&f, &Tensor::ones((idx.len(), 1), DType::F32, dev)?], 1)?;
    let mut acc = Tensor::zeros((), DType::F32, dev)?;
    for k in 0..=h {
        let y = set.targets(idx, k, dev)?;
        let e = z.narrow(1, 0, N_OBS)?.sub(&y)?;
        acc = acc.add(&e.sqr()?.mean_all()?)?;
        if k < h {
            z = z.matmul(kt)?;
        }
    }
    acc.affine(1.0 / (h + 1) as f64, 0.0)
}

/// Validation loss and per-horizon RMSE.
fn evaluate(
    net: &Net,
    set: &Set,
    kt: &Tensor,
    h: usize,
    dev: &Device,
) -> candle_core::Result<(f64, Vec<f64>)> {
    let mut sq = vec![0.0; h + 1];
    let mut n = 0usize;
    for chunk in set.windows.chunks(256) {
        let (x, s) = set.inputs(chunk, dev)?;
        let f = net.forward(&x, &s)?.detach();
        let mut z = Tensor::cat(&[&f, &Tensor::ones((chunk.len(), 1), DType::F32, dev)?], 1)?;
        for (k, acc) in sq.iter_mut().enumerate() {
            let y = set.targets(chunk, k, dev)?;
            let e = z.narrow(1, 0, N_OBS)?.sub(&y)?;
            *acc += e.sqr()?.sum_all()?.to_scalar::<f32>()? as f64;
            z = z.matmul(kt)?;
        }
        n += chunk.len();
    }
    let per: Vec<f64> = sq.iter().map(|v| (v / (n * N_OBS).max(1) as f64).sqrt()).collect();
    let loss = sq.iter().sum::<f64>() / ((n * N_OBS).max(1) * (h + 1)) as f64;
    Ok((loss, per))
}

/// Trains f_θ and `K` (Algorithm 1) on `train`, validating on `valid` (other runs).
pub fn train(
    train: &[Sequence],
    valid: &[Sequence],
    cfg: &VisualTrainConfig,
    progress: &mut dyn FnMut(&Progress),
) -> Result<(VisualNet, VisualTrainReport), VisualTrainError> {
    let t0 = Instant::now();
    if cfg.epochs == 0 || cfg.resolve_every == 0 || cfg.batch == 0 || cfg.horizon == 0 {
        return Err(VisualTrainError::Config("epochs, resolve_every, batch and horizon must be ≥ 1".into()));
    }
    if !(cfg.lr.is_finite() && cfg.lr > 0.0 && cfg.ridge.is_finite() && cfg.ridge >= 0.0) {
        return Err(VisualTrainError::Config(format!(
            "lr = {} and ridge = {} must be finite, lr > 0",
            cfg.lr, cfg.ridge
        )));
    }
    let h = cfg.horizon;
    let dev = Device::Cpu;
    let tset = Set::new(train, h)?;
    let vset = Set::new(valid, h)?;
    if tset.windows.is_empty() {
        return Err(VisualTrainError::Data(format!("no training sequence has more than {h} views")));
    }
    let eval_set = if vset.windows.is_empty() { &tset } else { &vset };
    let mut rng = SmallRng::seed_from_u64(cfg.seed);
    let net = Net::init(&mut rng, &dev)?;
    let mut opt = AdamW::new(
        net.vars.clone(),
        ParamsAdamW { lr: cfg.lr, beta1: 0.9, beta2: 0.999, eps: 1e-8, weight_decay: 0.0 },
    )?;
    let mut k = resolve_koopman(&net.features_all(&tset, &dev)?, &tset.pairs, cfg.ridge)?;
    let mut kt = kt_tensor(&k, &dev)?;
    let (initial, _) = evaluate(&net, eval_set, &kt, h, &dev)?;
    let mut best =
        (if initial.is_finite() { initial } else { f64::INFINITY }, 0usize, net.params()?, k.clone());
    let mut report = VisualTrainReport {
        initial_valid_loss: initial,
        train_loss: Vec::new(),
        valid_loss: Vec::new(),
        best_epoch: 0,
        valid_rmse: Vec::new(),
        valid_axis_err_rad: [f64::NAN; 2],
        train_windows: tset.windows.len(),
        valid_windows: vset.windows.len(),
        seconds: 0.0,
    };
    let mut order = tset.windows.clone();
    for epoch in 1..=cfg.epochs {
        if epoch > 1 && (epoch - 1).is_multiple_of(cfg.resolve_every) {
            k = resolve_koopman(&net.features_all(&tset, &dev)?, &tset.pairs, cfg.ridge)?;
            kt = kt_tensor(&k, &dev)?;
        }
        let frac = (epoch - 1) as f64 / cfg.epochs as f64;
        opt.set_learning_rate(cfg.lr * (0.05 + 0.95 * 0.5 * (1.0 + (std::f64::consts::PI * frac).cos())));
        for i in (1..order.len()).rev() {
            order.swap(i, rng.random_range(0..=i));
        }
        let take = order.len().min(cfg.max_windows);
        let (mut acc, mut nb) = (0.0, 0usize);
        for chunk in order[..take].chunks(cfg.batch) {
            let loss = window_loss(&net, &tset, chunk, &kt, h, &dev)?;
            let l = loss.to_scalar::<f32>()? as f64;
            if !l.is_finite() {
                return Err(VisualTrainError::Data(format!("epoch {epoch}: loss diverged")));
            }
            opt.backward_step(&loss)?;
            acc += l;
            nb += 1;
        }
        let train_loss = acc / nb.max(1) as f64;
        let (vl, _) = evaluate(&net, eval_set, &kt, h, &dev)?;
        report.train_loss.push(train_loss);
        report.valid_loss.push(vl);
        if vl < best.0 {
            best = (vl, epoch, net.params()?, k.clone());
        }
        progress(&Progress {
            epoch,
            epochs: cfg.epochs,
            train_loss,
            valid_loss: vl,
            elapsed_s: t0.elapsed().as_secs_f64(),
        });
    }
    net.set(&best.2)?;
    let kt = kt_tensor(&best.3, &dev)?;
    let (_, per) = evaluate(&net, eval_set, &kt, h, &dev)?;
    report.best_epoch = best.1;
    report.valid_rmse = per;
    report.valid_axis_err_rad = axis_errors(&net.features_all(eval_set, &dev)?, &eval_set.y);
    report.seconds = t0.elapsed().as_secs_f64();
    let vnet = VisualNet::from_parts(best.2, best.3)
        .ok_or_else(|| VisualTrainError::Data("parameter sizes differ from the architecture".into()))?;
    debug_assert_eq!(vnet.params().iter().map(|p| p.len()).collect::<Vec<_>>(), PARAM_SIZES.to_vec());
    Ok((vnet, report))
}

/// An untrained f_θ (the training's initial weights for `seed`) with `K = I`.
pub fn initial(seed: u64) -> Result<VisualNet, VisualTrainError> {
    let mut rng = SmallRng::seed_from_u64(seed);
    let net = Net::init(&mut rng, &Device::Cpu)?;
    let mut k = vec![0.0; P * P];
    (0..P).for_each(|i| k[i * P + i] = 1.0);
    VisualNet::from_parts(net.params()?, k)
        .ok_or_else(|| VisualTrainError::Data("parameter sizes differ from the architecture".into()))
}

/// f_θ of `net` on one view pair evaluated by candle (the training graph), to check the
/// fixed-array inference against.
pub fn candle_forward(net: &VisualNet, cur: &View, prev: &View) -> Result<[f64; N_OUT], VisualTrainError> {
    let dev = Device::Cpu;
    let n = Net::from_net(net, &dev)?;
    let mut x = cur.px.to_vec();
    x.extend_from_slice(&prev.px);
    let x = Tensor::from_vec(x, (1, IN_CH, CROP, CROP), &dev)?;
    let s = Tensor::from_vec(cur.scalars.to_vec(), (1, N_SCALARS), &dev)?;
    let f = n.forward(&x, &s)?.flatten_all()?.to_vec1::<f32>()?;
    Ok(std::array::from_fn(|i| f[i] as f64))
}

/// Median angles between the axes decoded from `features` and from the targets `y`, where
/// both are sure (long, short), rad.
pub fn axis_errors(features: &[f64], y: &[f32]) -> [f64; 2] {
    let mut errs = [Vec::new(), Vec::new()];
    for (f, t) in features.chunks_exact(N_OUT).zip(y.chunks_exact(N_OBS)) {
        let t: Vec<f64> = t.iter().map(|v| *v as f64).collect();
        let (p, _) = decode(&f[..N_OBS]);
        let (q, _) = decode(&t);
        for (h, (a, b)) in [(p.long, q.long), (p.short, q.short)].into_iter().enumerate() {
            if let (Some(a), Some(b)) = (a, b) {
                let d = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]).abs().min(1.0);
                errs[h].push(d.acos());
            }
        }
    }
    errs.map(|mut v| {
        if v.is_empty() {
            return f64::NAN;
        }
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    })
}

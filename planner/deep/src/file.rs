//! Versioned model file format (see the crate README for the byte layout).
//!
//! ```text
//! file   = header model* checksum
//! header = magic "DKRRTDKM" (8) | version u32 | total_len u64 | n_models u32
//! model  = record_len u64 | name_len u32 | name (UTF-8) | activation u32 | n u32 | hidden u32
//!          | layers u32 | extra u32 | dt f64 | offset n×f64 | scale n×f64
//!          | params param_count×f64 | A p×p f64 (column-major, p = n + extra)
//! checksum = FNV-1a 64 of all preceding bytes, u64
//! ```
//! All integers and floats little-endian; `record_len` counts the bytes after itself.

use crate::lifting::{param_count, DeepLifting, LiftingError, MAX_EXTRA, MAX_HIDDEN, MAX_IN, MAX_LAYERS};
use crate::DeepKoopman;
use dkrrt_koopman::KoopmanModel;
use std::path::Path;

/// Magic bytes at the start of every model file.
pub const MAGIC: [u8; 8] = *b"DKRRTDKM";
/// Model file format version written by this build (and the only one it reads).
pub const FORMAT_VERSION: u32 = 1;
/// Activation code of `tanh` hidden layers (the only one so far).
pub const ACTIVATION_TANH: u32 = 1;
/// Longest accepted model name in bytes.
pub const MAX_NAME_LEN: usize = 256;
/// Most models in one file.
pub const MAX_MODELS: usize = 1024;

const HEADER_LEN: usize = 8 + 4 + 8 + 4;
const CHECKSUM_LEN: usize = 8;

/// Why a model file could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum ModelFileError {
    /// Reading the file failed.
    #[error("cannot read model file: {0}")]
    Io(#[from] std::io::Error),
    /// The file does not start with [`MAGIC`].
    #[error("bad magic bytes {found:02x?}: not a dkrrt deep Koopman model file (expected \"DKRRTDKM\")")]
    BadMagic {
        /// The first (up to 8) bytes found.
        found: Vec<u8>,
    },
    /// Written by a different format version.
    #[error("unsupported model file format version {found} (this build supports version {supported})")]
    UnsupportedVersion {
        /// Version in the file.
        found: u32,
        /// [`FORMAT_VERSION`].
        supported: u32,
    },
    /// The data ends early.
    #[error("model file truncated while reading {what}: need {needed} bytes, have {have}")]
    Truncated {
        /// What was being read.
        what: String,
        /// Bytes needed.
        needed: u64,
        /// Bytes available.
        have: u64,
    },
    /// Extra bytes after the declared length, or records that do not fill it exactly.
    #[error("model file length mismatch: {0}")]
    LengthMismatch(String),
    /// Stored checksum differs from the computed one (corruption).
    #[error(
        "model file checksum mismatch: stored {stored:#018x}, computed {computed:#018x} (file is corrupt)"
    )]
    ChecksumMismatch {
        /// Checksum stored in the file.
        stored: u64,
        /// Checksum of the file content.
        computed: u64,
    },
    /// A dimension outside the supported range.
    #[error("model {model:?}: {field} = {value} out of range {min}..={max}")]
    DimensionOutOfRange {
        /// Model name.
        model: String,
        /// Which dimension.
        field: &'static str,
        /// Its value.
        value: u64,
        /// Smallest allowed.
        min: u64,
        /// Largest allowed.
        max: u64,
    },
    /// Dimensions that do not agree with each other (e.g. the record length).
    #[error("model {model:?}: inconsistent dimensions: {what}")]
    InconsistentDimensions {
        /// Model name.
        model: String,
        /// Description.
        what: String,
    },
    /// NaN / infinite value (or a non-positive scale or time step).
    #[error("model {model:?}: invalid (non-finite or non-positive) value in {field}[{index}]")]
    NonFinite {
        /// Model name.
        model: String,
        /// Which field.
        field: &'static str,
        /// Index of the first bad entry.
        index: usize,
    },
    /// Unknown activation code.
    #[error("model {model:?}: unknown activation code {code} (supported: 1 = tanh)")]
    UnknownActivation {
        /// Model name.
        model: String,
        /// The code.
        code: u32,
    },
    /// Model name not valid UTF-8, too long, or duplicated.
    #[error("bad model name: {0}")]
    BadName(String),
    /// The model's state dimension differs from what the caller needs.
    #[error("model {model:?} has state dimension {found}, but the caller expects {expected}")]
    WrongStateDim {
        /// Model name.
        model: String,
        /// Its state dimension.
        found: usize,
        /// The expected one.
        expected: usize,
    },
    /// No model of that name in the file.
    #[error("no model named {name:?} in the file (available: {available:?})")]
    NotFound {
        /// Requested name.
        name: String,
        /// Names in the file.
        available: Vec<String>,
    },
}

/// FNV-1a, 64 bit.
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

fn check_model(name: &str, m: &DeepKoopman) -> Result<(), String> {
    let l = &m.lifting;
    let n = dkrrt_koopman::Lifting::state_dim(l);
    let p = dkrrt_koopman::Lifting::dim(l);
    if name.len() > MAX_NAME_LEN {
        return Err(format!("model name longer than {MAX_NAME_LEN} bytes"));
    }
    if m.model.n != n || m.model.p != p || m.model.m != 0 || m.model.ab.len() != p * p {
        return Err(format!(
            "model {name:?}: KoopmanModel (n = {}, p = {}, m = {}) does not match the lifting (n = {n}, p = {p}, m = 0)",
            m.model.n, m.model.p, m.model.m
        ));
    }
    Ok(())
}

/// Serialise models (names must be unique, ≤ [`MAX_NAME_LEN`] bytes).
///
/// Panics if a model's `KoopmanModel` does not match its lifting (use [`save_models`] for an
/// error instead).
pub fn to_bytes(models: &[(&str, &DeepKoopman)]) -> Vec<u8> {
    for (name, m) in models {
        if let Err(e) = check_model(name, m) {
            panic!("to_bytes: {e}");
        }
    }
    let mut out = Vec::new();
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(&0u64.to_le_bytes()); // total_len, patched below
    out.extend_from_slice(&(models.len() as u32).to_le_bytes());
    for (name, m) in models {
        let l = &m.lifting;
        let mut rec = Vec::new();
        rec.extend_from_slice(&(name.len() as u32).to_le_bytes());
        rec.extend_from_slice(name.as_bytes());
        rec.extend_from_slice(&ACTIVATION_TANH.to_le_bytes());
        for d in [dkrrt_koopman::Lifting::state_dim(l), l.hidden(), l.layers(), l.extra()] {
            rec.extend_from_slice(&(d as u32).to_le_bytes());
        }
        rec.extend_from_slice(&m.model.dt.to_le_bytes());
        for v in l.offset().iter().chain(l.scale()).chain(l.params()).chain(&m.model.ab) {
            rec.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&(rec.len() as u64).to_le_bytes());
        out.extend_from_slice(&rec);
    }
    let total = (out.len() + CHECKSUM_LEN) as u64;
    out[12..20].copy_from_slice(&total.to_le_bytes());
    let sum = fnv1a64(&out);
    out.extend_from_slice(&sum.to_le_bytes());
    out
}

/// Write models to a file (atomically: a temporary file renamed into place).
pub fn save_models(path: &Path, models: &[(&str, &DeepKoopman)]) -> std::io::Result<()> {
    for (name, m) in models {
        check_model(name, m).map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidInput, e))?;
    }
    let mut seen = std::collections::HashSet::new();
    for (name, _) in models {
        if !seen.insert(*name) {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                format!("duplicate model name {name:?}"),
            ));
        }
    }
    let bytes = to_bytes(models);
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = std::path::PathBuf::from(tmp);
    std::fs::write(&tmp, &bytes)?;
    std::fs::rename(&tmp, path)
}

/// Read all models of a file.
pub fn load_models(path: &Path) -> Result<Vec<(String, DeepKoopman)>, ModelFileError> {
    from_bytes(&read(path)?)
}

fn read(path: &Path) -> std::io::Result<Vec<u8>> {
    Ok(dkrrt_io::read_capped(path, dkrrt_io::limits::MODEL)?)
}

/// Read one named model and check its state dimension.
pub fn load_model(path: &Path, name: &str, expected_n: usize) -> Result<DeepKoopman, ModelFileError> {
    select(from_bytes(&read(path)?)?, name, expected_n)
}

/// Pick the model `name` from a loaded list and check that its state dimension is `expected_n`.
pub fn select(
    models: Vec<(String, DeepKoopman)>,
    name: &str,
    expected_n: usize,
) -> Result<DeepKoopman, ModelFileError> {
    let available: Vec<String> = models.iter().map(|(n, _)| n.clone()).collect();
    let Some((_, m)) = models.into_iter().find(|(n, _)| n == name) else {
        return Err(ModelFileError::NotFound { name: name.to_string(), available });
    };
    if m.model.n != expected_n {
        return Err(ModelFileError::WrongStateDim {
            model: name.to_string(),
            found: m.model.n,
            expected: expected_n,
        });
    }
    Ok(m)
}

struct Reader<'a> {
    b: &'a [u8],
    pos: usize,
    end: usize,
}

impl Reader<'_> {
    fn take(&mut self, k: usize, what: &dyn Fn() -> String) -> Result<&[u8], ModelFileError> {
        if self.end - self.pos < k {
            return Err(ModelFileError::Truncated {
                what: what(),
                needed: (self.pos + k) as u64,
                have: self.end as u64,
            });
        }
        let s = &self.b[self.pos..self.pos + k];
        self.pos += k;
        Ok(s)
    }
    fn u32(&mut self, what: &dyn Fn() -> String) -> Result<u32, ModelFileError> {
        Ok(u32::from_le_bytes(self.take(4, what)?.try_into().unwrap()))
    }
    fn u64(&mut self, what: &dyn Fn() -> String) -> Result<u64, ModelFileError> {
        Ok(u64::from_le_bytes(self.take(8, what)?.try_into().unwrap()))
    }
    fn f64s(&mut self, k: usize, what: &dyn Fn() -> String) -> Result<Vec<f64>, ModelFileError> {
        let s = self.take(k * 8, what)?;
        Ok(s.chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().unwrap())).collect())
    }
}

/// Parse a model file image. Checks, in order: magic, version, declared length (truncation /
/// trailing bytes), checksum, then every record's dimensions, lengths and values.
pub fn from_bytes(bytes: &[u8]) -> Result<Vec<(String, DeepKoopman)>, ModelFileError> {
    let have = bytes.len() as u64;
    if bytes.len() < 8 || bytes[..8] != MAGIC {
        if bytes.len() < 8 && MAGIC.starts_with(bytes) {
            return Err(ModelFileError::Truncated { what: "magic".into(), needed: 8, have });
        }
        return Err(ModelFileError::BadMagic { found: bytes[..bytes.len().min(8)].to_vec() });
    }
    if bytes.len() < 12 {
        return Err(ModelFileError::Truncated { what: "format version".into(), needed: 12, have });
    }
    let version = u32::from_le_bytes(bytes[8..12].try_into().unwrap());
    if version != FORMAT_VERSION {
        return Err(ModelFileError::UnsupportedVersion { found: version, supported: FORMAT_VERSION });
    }
    if bytes.len() < HEADER_LEN + CHECKSUM_LEN {
        return Err(ModelFileError::Truncated {
            what: "header".into(),
            needed: (HEADER_LEN + CHECKSUM_LEN) as u64,
            have,
        });
    }
    let total = u64::from_le_bytes(bytes[12..20].try_into().unwrap());
    if total < (HEADER_LEN + CHECKSUM_LEN) as u64 {
        return Err(ModelFileError::LengthMismatch(format!(
            "declared total length {total} is shorter than the header"
        )));
    }
    if have < total {
        return Err(ModelFileError::Truncated {
            what: "file (declared total length)".into(),
            needed: total,
            have,
        });
    }
    if have > total {
        return Err(ModelFileError::LengthMismatch(format!(
            "{} trailing bytes after the declared total length {total}",
            have - total
        )));
    }
    let body_end = bytes.len() - CHECKSUM_LEN;
    let stored = u64::from_le_bytes(bytes[body_end..].try_into().unwrap());
    let computed = fnv1a64(&bytes[..body_end]);
    if stored != computed {
        return Err(ModelFileError::ChecksumMismatch { stored, computed });
    }
    let n_models = u32::from_le_bytes(bytes[20..24].try_into().unwrap()) as usize;
    if n_models > MAX_MODELS {
        return Err(ModelFileError::DimensionOutOfRange {
            model: String::new(),
            field: "n_models",
            value: n_models as u64,
            min: 0,
            max: MAX_MODELS as u64,
        });
    }
    let mut r = Reader { b: bytes, pos: HEADER_LEN, end: body_end };
    let mut out: Vec<(String, DeepKoopman)> = Vec::with_capacity(n_models);
    for k in 0..n_models {
        let rec_len = r.u64(&|| format!("record length of model #{k}"))?;
        let rec_start = r.pos;
        let name_len = r.u32(&|| format!("name length of model #{k}"))? as usize;
        if name_len > MAX_NAME_LEN {
            return Err(ModelFileError::BadName(format!(
                "model #{k}: name length {name_len} > {MAX_NAME_LEN}"
            )));
        }
        let name_bytes = r.take(name_len, &|| format!("name of model #{k}"))?;
        let name = String::from_utf8(name_bytes.to_vec())
            .map_err(|_| ModelFileError::BadName(format!("model #{k}: name is not valid UTF-8")))?;
        if out.iter().any(|(n, _)| *n == name) {
            return Err(ModelFileError::BadName(format!("duplicate model name {name:?}")));
        }
        let ctx = |f: &str| format!("{f} of model {name:?}");
        let activation = r.u32(&|| ctx("activation"))?;
        if activation != ACTIVATION_TANH {
            return Err(ModelFileError::UnknownActivation { model: name, code: activation });
        }
        let mut dims = [0usize; 4];
        let limits =
            [("n", 1, MAX_IN), ("hidden", 1, MAX_HIDDEN), ("layers", 1, MAX_LAYERS), ("extra", 1, MAX_EXTRA)];
        for (d, (field, min, max)) in dims.iter_mut().zip(limits) {
            let v = r.u32(&|| ctx(field))? as usize;
            if v < min || v > max {
                return Err(ModelFileError::DimensionOutOfRange {
                    model: name,
                    field,
                    value: v as u64,
                    min: min as u64,
                    max: max as u64,
                });
            }
            *d = v;
        }
        let [n, hidden, layers, extra] = dims;
        let p = n + extra;
        let np = param_count(n, hidden, layers, extra);
        let expected_rec = (4 + name_len + 4 + 16 + 8 + 8 * (2 * n + np + p * p)) as u64;
        if rec_len != expected_rec {
            return Err(ModelFileError::InconsistentDimensions {
                model: name,
                what: format!(
                    "record length {rec_len} but n = {n}, hidden = {hidden}, layers = {layers}, extra = {extra} need {expected_rec}"
                ),
            });
        }
        let dt = f64::from_le_bytes(r.take(8, &|| ctx("dt"))?.try_into().unwrap());
        if !(dt.is_finite() && dt > 0.0) {
            return Err(ModelFileError::NonFinite { model: name, field: "dt", index: 0 });
        }
        let offset = r.f64s(n, &|| ctx("offset"))?;
        let scale = r.f64s(n, &|| ctx("scale"))?;
        let params = r.f64s(np, &|| ctx("params"))?;
        let ab = r.f64s(p * p, &|| ctx("A"))?;
        debug_assert_eq!((r.pos - rec_start) as u64, rec_len);
        if let Some(index) = ab.iter().position(|v| !v.is_finite()) {
            return Err(ModelFileError::NonFinite { model: name, field: "A", index });
        }
        let lifting = match DeepLifting::new(n, hidden, layers, extra, &offset, &scale, &params) {
            Ok(l) => l,
            Err(LiftingError::Invalid { field, index }) => {
                return Err(ModelFileError::NonFinite { model: name, field, index })
            }
            Err(e) => {
                return Err(ModelFileError::InconsistentDimensions { model: name, what: e.to_string() })
            }
        };
        let model = KoopmanModel { n, p, m: 0, dt, ab };
        out.push((name, DeepKoopman { lifting, model }));
    }
    if r.pos != body_end {
        return Err(ModelFileError::LengthMismatch(format!(
            "{} unused bytes after the last model record",
            body_end - r.pos
        )));
    }
    Ok(out)
}

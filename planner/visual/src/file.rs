//! Versioned model file of f_θ and `K`.
//!
//! ```text
//! file     = magic "DKRRTVIS" (8) | version u32 | total_len u64 | arch | params | K | checksum
//! arch     = crop in_ch c1 c2 c3 hidden n_obs n_extra n_scalars (9 × u32)
//! params   = w1 b1 w2 b2 w3 b3 d1w d1b d2w d2b (f32, sizes from the architecture, see PARAM_SIZES)
//! K        = P × P f64, row-major (P = n_obs + n_extra + 1)
//! checksum = FNV-1a 64 of all preceding bytes, u64
//! ```
//! Little-endian throughout. A file is read only when its architecture is this build's.

use crate::{
    VisualNet, C1, C2, C3, CROP, HIDDEN, IN_CH, N_EXTRA, N_OBS, N_SCALARS, P, PARAM_NAMES, PARAM_SIZES,
};
use dkrrt_deep::file::fnv1a64;
use std::path::Path;

/// Magic bytes at the start of every visual model file.
pub const MAGIC: [u8; 8] = *b"DKRRTVIS";
/// Format version written and read by this build.
pub const FORMAT_VERSION: u32 = 1;
const ARCH_NAMES: [&str; 9] = ["crop", "in_ch", "c1", "c2", "c3", "hidden", "n_obs", "n_extra", "n_scalars"];
const ARCH: [usize; 9] = [CROP, IN_CH, C1, C2, C3, HIDDEN, N_OBS, N_EXTRA, N_SCALARS];
const HEADER_LEN: usize = 8 + 4 + 8;

/// Why a visual model file could not be read (each names the field).
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum VisualFileError {
    #[error("cannot read: {0}")]
    Io(String),
    #[error("magic: found {0:02x?}, expected \"DKRRTVIS\" (not a dkrrt visual model file)")]
    BadMagic(Vec<u8>),
    #[error("version: {found} is not supported (this build reads version {FORMAT_VERSION})")]
    UnsupportedVersion { found: u32 },
    #[error("truncated while reading {what}: need {needed} bytes, have {have}")]
    Truncated { what: &'static str, needed: usize, have: usize },
    #[error("total_len: the header says {declared} bytes, the file has {actual}")]
    LengthMismatch { declared: u64, actual: usize },
    #[error("checksum: stored {stored:#018x}, computed {computed:#018x} (the file is corrupt)")]
    Checksum { stored: u64, computed: u64 },
    #[error("arch.{field}: the file has {found}, this build's network has {expected}")]
    Architecture { field: &'static str, found: u32, expected: usize },
    #[error("{field}[{index}]: not finite")]
    NonFinite { field: &'static str, index: usize },
}

/// The file's bytes.
pub fn to_bytes(net: &VisualNet) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(&0u64.to_le_bytes());
    for a in ARCH {
        out.extend_from_slice(&(a as u32).to_le_bytes());
    }
    for p in net.params() {
        for v in p {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    for v in &net.k {
        out.extend_from_slice(&v.to_le_bytes());
    }
    let total = (out.len() + 8) as u64;
    out[12..20].copy_from_slice(&total.to_le_bytes());
    let sum = fnv1a64(&out);
    out.extend_from_slice(&sum.to_le_bytes());
    out
}

struct Reader<'a> {
    b: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take(&mut self, n: usize, what: &'static str) -> Result<&[u8], VisualFileError> {
        if self.b.len() - self.at < n {
            return Err(VisualFileError::Truncated { what, needed: n, have: self.b.len() - self.at });
        }
        self.at += n;
        Ok(&self.b[self.at - n..self.at])
    }
    fn u32(&mut self, what: &'static str) -> Result<u32, VisualFileError> {
        Ok(u32::from_le_bytes(self.take(4, what)?.try_into().expect("4 bytes")))
    }
}

/// Reads a network from bytes.
pub fn from_bytes(b: &[u8]) -> Result<VisualNet, VisualFileError> {
    let mut r = Reader { b, at: 0 };
    let magic = r.take(8, "magic").map_err(|_| VisualFileError::BadMagic(b[..b.len().min(8)].to_vec()))?;
    if magic != MAGIC {
        return Err(VisualFileError::BadMagic(magic.to_vec()));
    }
    let version = r.u32("version")?;
    if version != FORMAT_VERSION {
        return Err(VisualFileError::UnsupportedVersion { found: version });
    }
    let total = u64::from_le_bytes(r.take(8, "total_len")?.try_into().expect("8 bytes"));
    if total != b.len() as u64 {
        return Err(VisualFileError::LengthMismatch { declared: total, actual: b.len() });
    }
    let stored = u64::from_le_bytes(b[b.len().saturating_sub(8)..].try_into().unwrap_or([0; 8]));
    let computed = fnv1a64(&b[..b.len().saturating_sub(8)]);
    if b.len() < HEADER_LEN + 8 || stored != computed {
        return Err(VisualFileError::Checksum { stored, computed });
    }
    for (field, expected) in ARCH_NAMES.into_iter().zip(ARCH) {
        let found = r.u32(field)?;
        if found as usize != expected {
            return Err(VisualFileError::Architecture { field, found, expected });
        }
    }
    let mut params = Vec::with_capacity(PARAM_SIZES.len());
    for (field, n) in PARAM_NAMES.into_iter().zip(PARAM_SIZES) {
        let raw = r.take(4 * n, field)?;
        let v: Vec<f32> =
            raw.chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes"))).collect();
        if let Some(index) = v.iter().position(|x| !x.is_finite()) {
            return Err(VisualFileError::NonFinite { field, index });
        }
        params.push(v);
    }
    let raw = r.take(8 * P * P, "k")?;
    let k: Vec<f64> =
        raw.chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes"))).collect();
    if let Some(index) = k.iter().position(|x| !x.is_finite()) {
        return Err(VisualFileError::NonFinite { field: "k", index });
    }
    if r.at + 8 != b.len() {
        return Err(VisualFileError::LengthMismatch { declared: total, actual: r.at + 8 });
    }
    Ok(VisualNet::from_parts(params, k).expect("sizes read from the architecture"))
}

/// Writes `net` to `path` (a temporary file renamed into place).
pub fn save(path: &Path, net: &VisualNet) -> std::io::Result<()> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    std::fs::write(&tmp, to_bytes(net))?;
    std::fs::rename(&tmp, path)
}

/// Reads the network of `path`; the error names the file and the field.
pub fn load(path: &Path) -> Result<VisualNet, String> {
    let bytes = dkrrt_io::read_capped(path, dkrrt_io::limits::MODEL)
        .map_err(|e| format!("{}: {}", path.display(), VisualFileError::Io(e.to_string())))?;
    from_bytes(&bytes).map_err(|e| format!("{}: {e}", path.display()))
}

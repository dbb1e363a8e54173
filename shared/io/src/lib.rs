//! dkrrt-io: every file dkrrt is handed (scenario, URDF, debris scene, model file, planning
//! problem, recording) is read through here: only regular files (a device such as `/dev/zero`
//! or a FIFO is refused before it is opened for reading), and never more than a stated number
//! of bytes, so a wrong path cannot make a process read without limit.

use std::io::Read;
use std::path::Path;

/// Fixed-length arrays of numbers read exactly, for `#[serde(deserialize_with = ...)]`:
/// serde's own arrays silently drop extra elements (`p = [0, 0, 0, 5]` would pass as
/// `[0, 0, 0]`; `kp = [400, 400, 400, 400, 400, 400, -1, nan]` as six gains).
pub mod exact {
    use serde::{de::Error, Deserialize, Deserializer};

    fn exact<E: Error, const N: usize>(v: Vec<f64>) -> Result<[f64; N], E> {
        let n = v.len();
        v.try_into().map_err(|_| E::invalid_length(n, &format!("exactly {N} numbers").as_str()))
    }

    /// `[f64; N]`.
    pub fn array<'de, D: Deserializer<'de>, const N: usize>(d: D) -> Result<[f64; N], D::Error> {
        exact(Vec::<f64>::deserialize(d)?)
    }

    /// `Option<[f64; N]>` (with `#[serde(default)]` when it may be left out).
    pub fn opt_array<'de, D: Deserializer<'de>, const N: usize>(d: D) -> Result<Option<[f64; N]>, D::Error> {
        Option::<Vec<f64>>::deserialize(d)?.map(exact).transpose()
    }

    /// `Vec<[f64; N]>` (a list of points).
    pub fn arrays<'de, D: Deserializer<'de>, const N: usize>(d: D) -> Result<Vec<[f64; N]>, D::Error> {
        Vec::<Vec<f64>>::deserialize(d)?.into_iter().map(exact).collect()
    }
}

/// Size limits per kind of file, bytes.
pub mod limits {
    /// Scenario and debris-scene TOML files.
    pub const SCENARIO: u64 = 1 << 20;
    /// URDF files.
    pub const URDF: u64 = 16 << 20;
    /// Trained model files.
    pub const MODEL: u64 = 64 << 20;
    /// Planning problems and JSON statistics.
    pub const JSON: u64 = 256 << 20;
}

/// Why a file could not be read.
#[derive(Debug)]
pub enum ReadError {
    Io(std::io::Error),
    NotAFile,
    TooLarge { limit: u64 },
    NotUtf8,
}

impl std::fmt::Display for ReadError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ReadError::Io(e) => write!(f, "{e}"),
            ReadError::NotAFile => write!(f, "not a regular file"),
            ReadError::TooLarge { limit } => {
                write!(f, "larger than the {limit}-byte limit for this kind of file")
            }
            ReadError::NotUtf8 => write!(f, "not UTF-8 text"),
        }
    }
}

impl std::error::Error for ReadError {}

impl From<ReadError> for std::io::Error {
    fn from(e: ReadError) -> Self {
        match e {
            ReadError::Io(e) => e,
            other => std::io::Error::new(std::io::ErrorKind::InvalidData, other.to_string()),
        }
    }
}

/// Reads at most `limit` bytes of the regular file `path` (symlinks to regular files are
/// followed); more is an error, as is a device, FIFO, socket or directory.
pub fn read_capped(path: &Path, limit: u64) -> Result<Vec<u8>, ReadError> {
    let meta = std::fs::metadata(path).map_err(ReadError::Io)?;
    if !meta.is_file() {
        return Err(ReadError::NotAFile);
    }
    if meta.len() > limit {
        return Err(ReadError::TooLarge { limit });
    }
    let f = std::fs::File::open(path).map_err(ReadError::Io)?;
    // The file may grow between the check and the read: read one byte past the limit to see.
    let mut out = Vec::with_capacity(meta.len() as usize);
    f.take(limit + 1).read_to_end(&mut out).map_err(ReadError::Io)?;
    if out.len() as u64 > limit {
        return Err(ReadError::TooLarge { limit });
    }
    Ok(out)
}

/// [`read_capped`] for text files.
pub fn read_text_capped(path: &Path, limit: u64) -> Result<String, ReadError> {
    String::from_utf8(read_capped(path, limit)?).map_err(|_| ReadError::NotUtf8)
}

/// `s` with control characters (terminal escapes, newlines) shown as escapes, for error
/// messages that quote names or values from a file.
pub fn printable(s: &str) -> String {
    s.chars()
        .flat_map(|c| if c.is_control() { c.escape_default().collect::<Vec<_>>() } else { vec![c] })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn devices_and_oversized_files_are_refused() {
        assert!(matches!(read_capped(Path::new("/dev/zero"), 10), Err(ReadError::NotAFile)));
        assert!(matches!(read_capped(Path::new("/tmp"), 10), Err(ReadError::NotAFile)));
        let p = std::env::temp_dir().join(format!("dkrrt-io-{}", std::process::id()));
        std::fs::write(&p, [b'a'; 11]).unwrap();
        assert!(matches!(read_capped(&p, 10), Err(ReadError::TooLarge { limit: 10 })));
        assert_eq!(read_capped(&p, 11).unwrap().len(), 11);
        std::fs::write(&p, [0xff, 0xfe]).unwrap();
        assert!(matches!(read_text_capped(&p, 10), Err(ReadError::NotUtf8)));
        let _ = std::fs::remove_file(&p);
        assert!(matches!(read_capped(Path::new("/dev/null/x"), 10), Err(ReadError::Io(_))));
    }

    #[test]
    fn control_characters_are_escaped() {
        assert_eq!(printable("ok\u{1b}[31mred\n"), "ok\\u{1b}[31mred\\n");
        assert_eq!(printable("plain-name.toml"), "plain-name.toml");
    }
}

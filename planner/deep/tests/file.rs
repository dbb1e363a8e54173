//! Model file format: round trip and every load error.

use dkrrt_deep::*;
use dkrrt_koopman::KoopmanModel;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

fn random_model(n: usize, hidden: usize, layers: usize, extra: usize, seed: u64) -> DeepKoopman {
    let mut r = SmallRng::seed_from_u64(seed);
    let np = param_count(n, hidden, layers, extra);
    let params: Vec<f64> = (0..np).map(|_| r.random_range(-1.0..1.0)).collect();
    let offset: Vec<f64> = (0..n).map(|_| r.random_range(-1.0..1.0)).collect();
    let scale: Vec<f64> = (0..n).map(|_| r.random_range(0.1..2.0)).collect();
    let lifting = DeepLifting::new(n, hidden, layers, extra, &offset, &scale, &params).unwrap();
    let p = n + extra;
    let ab = (0..p * p).map(|_| r.random_range(-1.0..1.0)).collect();
    DeepKoopman { lifting, model: KoopmanModel { n, p, m: 0, dt: 0.1, ab } }
}

fn two_models() -> Vec<u8> {
    let a = random_model(7, 32, 2, 16, 1);
    let b = random_model(3, 8, 1, 4, 2);
    to_bytes(&[("attitude", &a), ("translation", &b)])
}

fn reseal(bytes: &mut [u8]) {
    let k = bytes.len() - 8;
    let sum = dkrrt_deep::file::fnv1a64(&bytes[..k]);
    bytes[k..].copy_from_slice(&sum.to_le_bytes());
}

#[test]
fn round_trip_is_bit_exact_with_several_named_models() {
    let a = random_model(7, 32, 2, 16, 1);
    let b = random_model(3, 64, 3, 32, 2);
    let bytes = to_bytes(&[("attitude", &a), ("translation", &b)]);
    let back = from_bytes(&bytes).unwrap();
    assert_eq!(back.len(), 2);
    assert_eq!(back[0].0, "attitude");
    assert_eq!(back[1].0, "translation");
    for ((_, m), orig) in back.iter().zip([&a, &b]) {
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(m.lifting.params()), bits(orig.lifting.params()));
        assert_eq!(bits(m.lifting.offset()), bits(orig.lifting.offset()));
        assert_eq!(bits(m.lifting.scale()), bits(orig.lifting.scale()));
        assert_eq!(bits(&m.model.ab), bits(&orig.model.ab));
        assert_eq!(m.model.dt.to_bits(), orig.model.dt.to_bits());
        assert_eq!((m.model.n, m.model.p, m.model.m), (orig.model.n, orig.model.p, 0));
    }
    // Re-serialising gives the same bytes.
    let again: Vec<(&str, &DeepKoopman)> = back.iter().map(|(n, m)| (n.as_str(), m)).collect();
    assert_eq!(to_bytes(&again), bytes);
    // Through the file system, and by name with the expected state dimension.
    let dir = std::env::temp_dir().join(format!("dkrrt-deep-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("models.dkm");
    save_models(&path, &[("attitude", &a), ("translation", &b)]).unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), bytes);
    let m = load_model(&path, "translation", 3).unwrap();
    assert_eq!(m.model.ab, b.model.ab);
    assert_eq!(load_models(&path).unwrap().len(), 2);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn empty_file_with_zero_models_round_trips() {
    let bytes = to_bytes(&[]);
    assert!(from_bytes(&bytes).unwrap().is_empty());
}

#[test]
fn bad_magic() {
    let mut b = two_models();
    b[0] = b'X';
    let e = from_bytes(&b).unwrap_err();
    assert!(matches!(e, ModelFileError::BadMagic { .. }), "{e}");
    assert!(e.to_string().contains("bad magic"), "{e}");
    assert!(matches!(from_bytes(b"hello world, not a model").unwrap_err(), ModelFileError::BadMagic { .. }));
}

#[test]
fn unsupported_version_names_found_and_supported() {
    let mut b = two_models();
    b[8..12].copy_from_slice(&(FORMAT_VERSION + 1).to_le_bytes());
    let e = from_bytes(&b).unwrap_err();
    match &e {
        ModelFileError::UnsupportedVersion { found, supported } => {
            assert_eq!((*found, *supported), (FORMAT_VERSION + 1, FORMAT_VERSION))
        }
        other => panic!("wrong error {other}"),
    }
    assert!(e.to_string().contains(&format!("version {}", FORMAT_VERSION + 1)), "{e}");
}

#[test]
fn truncated_at_every_length_is_an_error() {
    let b = two_models();
    for len in [0, 4, 8, 10, 12, 20, 30, b.len() / 2, b.len() - 9, b.len() - 1] {
        let e = from_bytes(&b[..len]).unwrap_err();
        assert!(matches!(e, ModelFileError::Truncated { .. }), "len {len}: {e}");
    }
    let e = from_bytes(&b[..b.len() - 1]).unwrap_err();
    assert!(e.to_string().contains("truncated"), "{e}");
}

#[test]
fn trailing_bytes_are_rejected() {
    let mut b = two_models();
    b.push(0);
    assert!(matches!(from_bytes(&b).unwrap_err(), ModelFileError::LengthMismatch(_)));
}

#[test]
fn flipped_byte_anywhere_in_the_body_is_a_checksum_mismatch() {
    let b = two_models();
    for pos in [24, 40, 100, b.len() / 2, b.len() - 9, b.len() - 1] {
        let mut c = b.clone();
        c[pos] ^= 0x10;
        let e = from_bytes(&c).unwrap_err();
        assert!(matches!(e, ModelFileError::ChecksumMismatch { .. }), "pos {pos}: {e}");
    }
}

/// Byte offset of model 0's dimension fields (after record_len, name_len, name, activation).
fn dims_offset(name: &str) -> usize {
    24 + 8 + 4 + name.len() + 4
}

#[test]
fn dimension_out_of_range() {
    let mut b = two_models();
    let o = dims_offset("attitude");
    b[o + 4..o + 8].copy_from_slice(&(MAX_HIDDEN as u32 + 1).to_le_bytes()); // hidden
    reseal(&mut b);
    match from_bytes(&b).unwrap_err() {
        ModelFileError::DimensionOutOfRange { model, field, value, .. } => {
            assert_eq!((model.as_str(), field, value), ("attitude", "hidden", MAX_HIDDEN as u64 + 1))
        }
        e => panic!("wrong error {e}"),
    }
    let mut b = two_models();
    b[o..o + 4].copy_from_slice(&0u32.to_le_bytes()); // n = 0
    reseal(&mut b);
    assert!(matches!(from_bytes(&b).unwrap_err(), ModelFileError::DimensionOutOfRange { field: "n", .. }));
}

#[test]
fn inconsistent_dimensions() {
    // Change `extra` 16 → 15: the record length no longer matches the dimensions.
    let mut b = two_models();
    let o = dims_offset("attitude");
    b[o + 12..o + 16].copy_from_slice(&15u32.to_le_bytes());
    reseal(&mut b);
    let e = from_bytes(&b).unwrap_err();
    assert!(matches!(e, ModelFileError::InconsistentDimensions { .. }), "{e}");
    assert!(e.to_string().contains("record length"), "{e}");
}

#[test]
fn non_finite_values_are_rejected() {
    let a = random_model(2, 4, 1, 2, 3);
    let base = to_bytes(&[("m", &a)]);
    let o = dims_offset("m") + 16; // dt
    for (field, at) in
        [("dt", o), ("offset", o + 8), ("scale", o + 24), ("params", o + 40), ("A", base.len() - 16)]
    {
        let mut b = base.clone();
        b[at..at + 8].copy_from_slice(&f64::NAN.to_le_bytes());
        reseal(&mut b);
        match from_bytes(&b).unwrap_err() {
            ModelFileError::NonFinite { field: f, .. } => assert_eq!(f, field),
            e => panic!("{field}: wrong error {e}"),
        }
    }
}

#[test]
fn wrong_state_dimension_and_missing_name() {
    let models = from_bytes(&two_models()).unwrap();
    match select(models.clone(), "attitude", 13).unwrap_err() {
        ModelFileError::WrongStateDim { model, found, expected } => {
            assert_eq!((model.as_str(), found, expected), ("attitude", 7, 13))
        }
        e => panic!("wrong error {e}"),
    }
    assert!(matches!(select(models.clone(), "nope", 7).unwrap_err(), ModelFileError::NotFound { .. }));
    assert_eq!(select(models, "attitude", 7).unwrap().model.n, 7);
}

#[test]
fn unknown_activation_and_bad_name() {
    let mut b = two_models();
    let o = dims_offset("attitude") - 4;
    b[o..o + 4].copy_from_slice(&7u32.to_le_bytes());
    reseal(&mut b);
    assert!(matches!(from_bytes(&b).unwrap_err(), ModelFileError::UnknownActivation { code: 7, .. }));
    let mut b = two_models();
    b[24 + 12] = 0xff; // first name byte: invalid UTF-8
    reseal(&mut b);
    assert!(matches!(from_bytes(&b).unwrap_err(), ModelFileError::BadName(_)));
    let a = random_model(2, 4, 1, 2, 3);
    let b = to_bytes(&[("same", &a), ("same", &a)]);
    assert!(matches!(from_bytes(&b).unwrap_err(), ModelFileError::BadName(_)));
    let dir = std::env::temp_dir();
    assert!(save_models(&dir.join("dkrrt-deep-dup.dkm"), &[("same", &a), ("same", &a)]).is_err());
}

#[test]
fn missing_file_is_an_io_error() {
    let e = load_models(std::path::Path::new("/dev/null/dkrrt/model.dkm")).unwrap_err();
    assert!(matches!(e, ModelFileError::Io(_)), "{e}");
}

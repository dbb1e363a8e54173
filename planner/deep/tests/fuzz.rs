//! Fuzzing the model file loader (proptest, bounded): random bytes, and valid files with
//! bytes flipped or cut (checksum resealed, so the parser behind it is reached), are refused
//! with an error or loaded — never a panic, never an allocation beyond the file's own size.

use dkrrt_deep::*;
use dkrrt_koopman::KoopmanModel;
use proptest::prelude::*;

fn model() -> Vec<u8> {
    let (n, hidden, layers, extra) = (3, 4, 1, 2);
    let np = param_count(n, hidden, layers, extra);
    let params: Vec<f64> = (0..np).map(|i| (i as f64 * 0.37).sin()).collect();
    let lifting = DeepLifting::new(n, hidden, layers, extra, &[0.0; 3], &[1.0; 3], &params).unwrap();
    let p = n + extra;
    let ab = (0..p * p).map(|i| (i as f64 * 0.11).cos()).collect();
    let m = DeepKoopman { lifting, model: KoopmanModel { n, p, m: 0, dt: 0.1, ab } };
    to_bytes(&[("attitude", &m)])
}

fn reseal(bytes: &mut [u8]) {
    if bytes.len() >= 8 {
        let k = bytes.len() - 8;
        let sum = dkrrt_deep::file::fnv1a64(&bytes[..k]);
        bytes[k..].copy_from_slice(&sum.to_le_bytes());
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 500, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn random_bytes_never_panic(b in prop::collection::vec(any::<u8>(), 0..512)) {
        let _ = dkrrt_deep::file::from_bytes(&b);
    }

    #[test]
    fn corrupted_files_never_panic(flips in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..6), cut in any::<prop::sample::Index>(), truncate in any::<bool>()) {
        let mut b = model();
        for (i, v) in flips {
            let k = i.index(b.len() - 8);
            b[k] = v;
        }
        if truncate {
            let n = cut.index(b.len());
            b.truncate(n);
        }
        reseal(&mut b);
        if let Ok(models) = dkrrt_deep::file::from_bytes(&b) {
            for (_, m) in &models {
                prop_assert!(m.model.n > 0 && m.model.p >= m.model.n);
            }
        }
    }
}

//! Test data generators (re-exported from the crate).
#![allow(unused_imports)]

pub use dkrrt_deep::testdata::*;

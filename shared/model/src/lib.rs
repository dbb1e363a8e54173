//! dkrrt-model

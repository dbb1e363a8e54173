//! dkrrt-rt

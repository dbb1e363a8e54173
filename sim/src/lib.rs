//! dkrrt-sim

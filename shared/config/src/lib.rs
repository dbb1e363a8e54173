//! dkrrt-config

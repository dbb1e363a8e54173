//! dkrrt-debris

//! dkrrt-otg

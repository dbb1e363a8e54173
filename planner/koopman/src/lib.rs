//! dkrrt-koopman

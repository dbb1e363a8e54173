//! dkrrt-msg

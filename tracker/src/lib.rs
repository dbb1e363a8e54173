//! dkrrt-tracker

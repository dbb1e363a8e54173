//! dkrrt-tracker: the 1 kHz computed-torque tracker.
//!
//! * [`ctrl`]: the controller core (no IPC): computed torque, delay
//!   compensation, safe hold (brake to rest with dkrrt-otg, then hold).
//! * [`process`]: the `dkrrt tracker` process shell.

pub mod ctrl;
pub mod process;

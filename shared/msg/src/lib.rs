//! dkrrt-msg: the message contract of dkrrt.
//!
//! Every inter-process payload is one fixed-size `#[repr(C)]` type defined
//! here (and only here, so every process agrees on the layout), with a common
//! [`Header`] and a `validate()` that rejects non-finite and out-of-range
//! values with a typed [`ValidationError`]. [`bus`] wires them to iceoryx2.
//! `docs/messages.md` lists every service, its type, size and rate.

pub mod bus;
pub mod traj;
pub mod types;
pub mod used;
pub mod validate;

pub use traj::JointSample;
pub use types::*;
pub use used::UsedPart;
pub use validate::{ContractLimits, Validate, ValidationError};

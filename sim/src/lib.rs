//! dkrrt-sim: the plant simulator.
//!
//! * [`plant`]: the plant core, a library with a step function, usable without IPC.
//! * [`debris`]: the debris world, its sensor and the per-tick arm–debris contact check.
//! * [`process`]: the `dkrrt sim` process shell (iceoryx2 + clock).

pub mod debris;
pub mod plant;
pub mod process;

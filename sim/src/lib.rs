//! dkrrt-sim: the plant simulator.
//!
//! * [`plant`]: the plant core, a library with a step function, usable without IPC.
//! * [`process`]: the `dkrrt sim` process shell (iceoryx2 + clock).

pub mod plant;
pub mod process;

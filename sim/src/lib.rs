//! dkrrt-sim: the plant simulator.
//!
//! * [`plant`]: the plant core, a library with a step function, usable without IPC.
//! * [`debris`]: the debris world, its sensor and the per-tick arm–debris contact check.
//! * [`camera`]: the depth camera's plant-clock schedule, its snapshots of the scene and
//!   their rendering into `DepthImage` messages.
//! * [`oracle`]: the recorded true future of the debris (the `oracle-rrt` method's forecasts).
//! * [`core`]: the simulator's tick (plant + debris + contact check + sensor), shared by the
//!   process and the in-process lockstep.
//! * [`stop`]: the controlled stop of a session (every driver's policy).
//! * [`process`]: the `dkrrt sim` process shell (iceoryx2 + clock).

pub mod camera;
pub mod camera_proc;
pub mod core;
pub mod debris;
pub mod oracle;
pub mod plant;
pub mod process;
pub mod stop;

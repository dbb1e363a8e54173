//! dkrrt-udp-driver: the network arm driver. It takes the simulator's place in the process set
//! (docs/driver-contract.md) and talks to an arm over dkrrt's UDP protocol
//! (docs/udp-protocol.md): the arm's states become `dkrrt/robot_state`, the tracker's
//! `dkrrt/torque_command` become command datagrams.
//!
//! * [`core`]: the driver side of the protocol as plain step functions (clock mapping,
//!   state/command matching, the link's figures), tested without sockets or IPC;
//! * [`process`]: the `dkrrt udp-driver` process shell (socket, bus, the session's controlled
//!   stop, optionally the simulated debris perception).

pub mod core;
pub mod process;

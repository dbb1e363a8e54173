//! dkrrt: Deep Koopman RRT for a 6-DoF space manipulator, as a set of
//! cooperating real-time processes over iceoryx2 shared memory.
//!
//! This crate is the `dkrrt` command: the launcher ([`launch`]), the
//! in-process lockstep evaluator ([`lockstep`]) and the CLI that starts each
//! process shell (`dkrrt sim`, `dkrrt tracker`, `dkrrt goto`, `dkrrt predictor`), plus
//! `dkrrt train` / `dkrrt predict-eval` ([`train`]).

pub mod ahead;
pub mod depth_view;
pub mod faults;
pub mod figures;
pub mod latency;
pub mod launch;
pub mod lockstep;
pub mod mcap_io;
pub mod plan_cli;
pub mod study;
pub mod study_report;
pub mod train;
pub mod verdict;
pub mod visual_train;

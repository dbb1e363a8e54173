//! dkrrt-planner

//! Writing simulation results to files other tools read.

pub mod pvd;
pub mod vtu;

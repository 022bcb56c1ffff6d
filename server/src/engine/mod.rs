//! The simulation, synchronous and free of networking: plain data in, plain data out.
//!
//! Stages: [`mesh`] (loading and topology), [`material`], [`elastic`] (tensor-mass
//! stiffness), [`integrate`] (explicit, implicit, static), [`contact`] (paper §2),
//! [`local_model`] (reaction forces, paper §3), [`scene`] (what a scene declares),
//! [`simulation`] (a scene built, and its tick: the stages in order).
//!
//! Each stage imports only the stages before it in that list; any may use
//! [`workers`], the threads a stage shares its loops with.

pub mod contact;
pub mod elastic;
pub mod integrate;
pub mod local_model;
pub mod material;
pub mod mesh;
pub mod scene;
pub mod simulation;
pub mod workers;

#[cfg(test)]
pub(crate) mod testing;

//! The simulation, synchronous and free of networking: plain data in, plain data out.
//!
//! Stages: [`mesh`] (loading and topology), [`material`], [`elastic`] (tensor-mass
//! stiffness), [`integrate`] (explicit, implicit, static), [`contact`] (paper §2),
//! [`local_model`] (reaction forces, paper §3), [`scene`] (what a scene declares, and
//! building only that).

pub mod contact;
pub mod elastic;
pub mod integrate;
pub mod local_model;
pub mod material;
pub mod mesh;
pub mod scene;

#[cfg(test)]
pub(crate) mod testing;

//! Scenes: what a simulation declares, read from TOML and checked.
//!
//! A scene declares what it uses — its mesh and scale, materials, supports, gravity,
//! integrator and rate, instruments, force model and recording — and
//! [`Scene::build`] (in [`crate::engine::simulation`]) builds only that. Every
//! quantity is in SI units once loaded (positions in metres after `mesh.scale`).
//!
//! Reading is strict: an unknown key, a value of the wrong type, or a value out of
//! range is an error that names the key's path (`material.poisson_ratio`,
//! `instruments[1].radius`) and, for syntax and type errors, the line.

mod error;
mod files;
pub mod limits;
mod schema;

pub use error::SceneError;
pub use files::{
    FileError, MAX_MESH_BYTES, MAX_SCENE_BYTES, file_kind, open_nonblocking, read_bounded,
    same_file,
};
pub use schema::{
    BoxSpec, FixedSpec, ForceModelSpec, InstrumentSpec, MAX_REFINE, MAX_REFINED_TETS, MaterialSpec,
    MechanicsSpec, MeshSpec, RecordingSpec, RegionSpec, Scene,
};

/// The default scene, embedded in the binary: SOFA's liver scaled to about 0.2 m,
/// liver-like material, held where a liver attaches, two instruments.
pub const DEFAULT_SCENE: &str = include_str!("../../../scenes/default.toml");

/// Meshes embedded in the binary, addressed in scenes as `builtin:NAME`.
pub const BUILTIN_MESHES: &[(&str, &str)] =
    &[("liver.msh", include_str!("../../../meshes/liver.msh"))];

#[cfg(test)]
pub(crate) mod tests;

//! A built scene, advanced one mechanics tick at a time.
//!
//! [`Scene::build`](crate::engine::scene::Scene::build) makes a [`Simulation`] of what
//! the scene declares, one concern a file: its mesh loaded, scaled and centred
//! (`mesh`), the materials of its regions (`materials`), its supports (`fixed`), the
//! rigid-motion check a static scene needs (`rigid`), its instruments (`instruments`),
//! and the assembly of the stages (`build`). [`Simulation::tick`] (`tick`) runs the
//! stages of one tick in the paper's order, each timed in a [`TickTiming`] field
//! (`timing`).

mod build;
mod fixed;
mod instruments;
mod materials;
mod mesh;
mod rigid;
mod tick;
mod timing;

pub use mesh::{RENUMBER_VERTICES, mesh_path};
pub use timing::TickTiming;

use nalgebra::Vector3;

use crate::engine::contact::{ContactStage, Instrument, InstrumentPose};
use crate::engine::elastic::ElasticModel;
use crate::engine::integrate::{Imposed, Integrator, State, StepReport};
use crate::engine::local_model::LocalModelStage;
use crate::engine::mesh::TetMesh;
use crate::engine::scene::Scene;

/// A built scene: the liver's mesh, elastic model and state, its supports, and the
/// integrator, advanced one mechanics tick at a time.
#[derive(Debug)]
pub struct Simulation {
    pub scene: Scene,
    /// The mesh, in metres.
    pub mesh: TetMesh,
    pub model: ElasticModel,
    pub state: State,
    /// Imposed vertices: the fixed supports and the vertices instruments hold.
    pub imposed: Imposed,
    pub integrator: Integrator,
    /// Gravity, m/s².
    pub gravity: Vector3<f64>,
    /// Tick length `1 / rate_hz`, s.
    pub dt: f64,
    /// The fixed vertices, sorted.
    pub fixed: Vec<u32>,
    /// The scene's instruments, in declaration order.
    pub instruments: Vec<Instrument>,
    /// The contact stage; built only for a scene with instruments that push tissue.
    pub contact: Option<ContactStage>,
    /// The force stage (local models and forces); built with the contact stage.
    pub forces: Option<LocalModelStage>,
    /// How long the last tick's stages took.
    pub last_timing: TickTiming,
    /// Ticks done.
    pub tick: u64,
    /// Simulated time, s.
    pub time: f64,
}

impl Simulation {
    /// Sets where instrument `k` is for the next tick; `None` takes it out of the body.
    pub fn set_pose(&mut self, k: usize, pose: Option<InstrumentPose>) {
        self.instruments[k].current = pose;
    }

    /// Jumps to the static equilibrium of the current supports and loads.
    pub fn solve_static(&mut self) -> StepReport {
        self.integrator
            .solve_static(&self.model, &mut self.state, &self.imposed, self.gravity)
    }

    /// Whether the fixed vertices remove every rigid motion, as a static solve needs.
    pub fn supports_hold_rigid_motion(&self) -> bool {
        rigid::removes_rigid_motion(&self.mesh.positions, &self.fixed)
    }

    /// Largest displacement magnitude, m.
    pub fn max_displacement(&self) -> f64 {
        self.state
            .x
            .iter()
            .zip(&self.model.rest)
            .map(|(x, r)| (x - r).norm())
            .fold(0.0, f64::max)
    }
}

#[cfg(test)]
mod tests;

//! Building a simulation from a scene: only what the scene declares.

use nalgebra::Vector3;

use super::{Simulation, TickTiming, fixed, instruments, materials, mesh, rigid};
use crate::engine::contact::{ContactStage, Instrument};
use crate::engine::elastic::ElasticModel;
use crate::engine::integrate::{Imposed, Integrator, IntegratorConfig, IntegratorKind, State};
use crate::engine::local_model::LocalModelStage;
use crate::engine::mesh::TetMesh;
use crate::engine::scene::{Scene, SceneError};

impl Scene {
    /// Loads the mesh and builds the simulation the scene declares.
    pub fn build(&self) -> Result<Simulation, SceneError> {
        self.build_on(self.load_mesh()?)
    }

    /// The scene's mesh as [`build`](Self::build) loads it: read, refined,
    /// renumbered, scaled and centred, in metres.
    pub fn load_mesh(&self) -> Result<TetMesh, SceneError> {
        mesh::load(self)
    }

    /// Builds the simulation on an already loaded mesh (in metres).
    pub fn build_on(&self, mesh: TetMesh) -> Result<Simulation, SceneError> {
        let (materials, tet_material) = materials::materials(self, &mesh)?;
        let fixed = fixed::fixed_vertices(self, &mesh)?;
        let model =
            ElasticModel::with_formulation(&mesh, materials, tet_material, self.material.model);
        let mut imposed = Imposed::new(mesh.vertex_count());
        for &i in &fixed {
            imposed.set(i, mesh.positions[i as usize]);
        }
        let m = &self.mechanics;
        if m.integrator == IntegratorKind::Static
            && !rigid::removes_rigid_motion(&mesh.positions, &fixed)
        {
            return Err(self.invalid(
                "fixed",
                "a static scene needs at least three fixed vertices that are not on one line",
            ));
        }
        let config = IntegratorConfig {
            kind: m.integrator,
            damping: m.damping,
            cg_tolerance: m.cg_tolerance,
            cg_max_iterations: m.cg_max_iterations,
            preconditioner: m.preconditioner,
            threads: m.threads,
            storage: m.stiffness,
            ..IntegratorConfig::default()
        };
        let mut integrator = Integrator::new(config, &model);
        self.check_tick_work(&integrator, mesh.vertex_count(), 1.0 / m.rate_hz)?;
        integrator.prepare(&model, imposed.mask(), 1.0 / m.rate_hz);
        let state = State::at_rest(&model);
        let instruments: Vec<Instrument> = self
            .instruments
            .iter()
            .map(|spec| instruments::instrument(spec, mesh.vertex_count()))
            .collect();
        let pushes = instruments.iter().any(|i| i.tip_contact || i.shaft_contact);
        let contact = pushes.then(|| {
            ContactStage::new(&mesh.surface, &mesh.positions, &fixed, instruments.len())
                .with_settling(self.contact.settle, model.elements.len())
                .with_footprint(self.contact.footprint)
        });
        let forces = pushes
            .then(|| LocalModelStage::new(self.force_model.kind, &mesh, &model, &instruments));
        Ok(Simulation {
            scene: self.clone(),
            gravity: Vector3::from(self.gravity),
            dt: 1.0 / m.rate_hz,
            mesh,
            model,
            state,
            imposed,
            integrator,
            fixed,
            instruments,
            contact,
            forces,
            last_timing: TickTiming::default(),
            tick: 0,
            time: 0.0,
        })
    }
}

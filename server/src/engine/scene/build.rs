//! Building a simulation from a scene: only what the scene declares.

use std::path::PathBuf;
use std::time::Instant;

use nalgebra::{Point3, Vector3};

use super::{Scene, SceneError};
use crate::engine::contact::{ContactStage, Instrument, InstrumentPose};
use crate::engine::elastic::ElasticModel;
use crate::engine::integrate::{
    Imposed, Integrator, IntegratorConfig, IntegratorKind, State, StepReport,
};
use crate::engine::local_model::LocalModelStage;
use crate::engine::material::Material;
use crate::engine::mesh::{MeshError, MeshErrorKind, TetMesh, read_gmsh};

/// A built scene: the liver's mesh, elastic model and state, its supports, and the
/// integrator, advanced one mechanics tick at a time.
#[derive(Debug)]
pub struct Simulation {
    pub scene: Scene,
    /// The mesh, in metres.
    pub mesh: TetMesh,
    pub model: ElasticModel,
    pub state: State,
    /// Imposed vertices: the fixed supports (and, later, instrument-held vertices).
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

/// Wall time of one tick's stages, s: what benchmarks and the session report.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TickTiming {
    /// The elastic step (the integrator).
    pub elastic: f64,
    /// The contact stage, before and after the elastic step.
    pub contact: f64,
    /// The force stage: local models and forces.
    pub forces: f64,
}

impl Simulation {
    /// Sets where instrument `k` is for the next tick; `None` takes it out of the body.
    pub fn set_pose(&mut self, k: usize, pose: Option<InstrumentPose>) {
        self.instruments[k].current = pose;
    }

    /// Advances one mechanics tick: held vertices follow their instruments, the elastic
    /// step moves the liver, the contact stage keeps it out of the instruments.
    pub fn tick(&mut self) -> StepReport {
        let t0 = Instant::now();
        if let Some(contact) = &mut self.contact {
            contact.before_step(
                &mut self.instruments,
                &self.mesh.surface,
                &self.state,
                &mut self.imposed,
            );
        }
        let t1 = Instant::now();
        let report = self.integrator.step(
            &self.model,
            &mut self.state,
            &self.imposed,
            self.gravity,
            self.dt,
        );
        let t2 = Instant::now();
        if let Some(contact) = &mut self.contact {
            contact.after_step(
                &mut self.instruments,
                &self.mesh.surface,
                &self.model,
                &mut self.state,
                &mut self.imposed,
                self.dt,
            );
        }
        let t3 = Instant::now();
        self.tick += 1;
        self.time += self.dt;
        if let Some(forces) = &mut self.forces {
            forces.update(
                self.tick,
                self.time,
                &self.instruments,
                &self.mesh.surface,
                &self.state.x,
            );
        }
        let t4 = Instant::now();
        self.last_timing = TickTiming {
            elastic: (t2 - t1).as_secs_f64(),
            contact: ((t1 - t0) + (t3 - t2)).as_secs_f64(),
            forces: (t4 - t3).as_secs_f64(),
        };
        report
    }

    /// Jumps to the static equilibrium of the current supports and loads.
    pub fn solve_static(&mut self) -> StepReport {
        self.integrator
            .solve_static(&self.model, &mut self.state, &self.imposed, self.gravity)
    }

    /// Whether the fixed vertices remove every rigid motion, as a static solve needs.
    pub fn supports_hold_rigid_motion(&self) -> bool {
        removes_rigid_motion(&self.mesh.positions, &self.fixed)
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

impl Scene {
    /// Loads the mesh and builds the simulation the scene declares.
    pub fn build(&self) -> Result<Simulation, SceneError> {
        let mut mesh = self.load_mesh()?;
        mesh.scale(self.mesh.scale);
        if self.mesh.center {
            let (lo, hi) = mesh.bounding_box();
            let c = (lo.coords + hi.coords) / 2.0;
            for p in &mut mesh.positions {
                *p -= c;
            }
        }
        self.check_mesh_extent(&mesh)?;
        self.build_on(mesh)
    }

    /// Builds the simulation on an already loaded mesh (in metres).
    pub fn build_on(&self, mesh: TetMesh) -> Result<Simulation, SceneError> {
        let (materials, tet_material) = self.materials(&mesh)?;
        let fixed = self.fixed_vertices(&mesh)?;
        let model = ElasticModel::new(&mesh, materials, tet_material);
        let mut imposed = Imposed::new(mesh.vertex_count());
        for &i in &fixed {
            imposed.set(i, mesh.positions[i as usize]);
        }
        let m = &self.mechanics;
        if m.integrator == IntegratorKind::Static && !removes_rigid_motion(&mesh.positions, &fixed)
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
            ..IntegratorConfig::default()
        };
        let integrator = Integrator::new(config, &model);
        self.check_tick_work(&integrator, mesh.vertex_count(), 1.0 / m.rate_hz)?;
        let state = State::at_rest(&model);
        let instruments: Vec<Instrument> = self
            .instruments
            .iter()
            .map(|spec| Instrument::new(spec, mesh.vertex_count()))
            .collect();
        let pushes = instruments.iter().any(|i| i.tip_contact || i.shaft_contact);
        let contact = pushes
            .then(|| ContactStage::new(&mesh.surface, &mesh.positions, &fixed, instruments.len()));
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

    fn load_mesh(&self) -> Result<TetMesh, SceneError> {
        let wrap = |source| SceneError::Mesh {
            scene: self.source.clone(),
            source,
        };
        if let Some(name) = self.mesh.file.strip_prefix("builtin:") {
            let (_, text) = super::BUILTIN_MESHES
                .iter()
                .find(|(n, _)| *n == name)
                .ok_or_else(|| self.invalid("mesh.file", format!("no built-in mesh `{name}`")))?;
            return read_gmsh(text, &self.mesh.file).map_err(wrap);
        }
        let mut path = PathBuf::from(&self.mesh.file);
        if path.is_relative()
            && let Some(dir) = &self.base_dir
        {
            path = dir.join(path);
        }
        let source = path.display().to_string();
        let bytes =
            match super::read_bounded(&path, self.mesh_root.as_deref(), super::MAX_MESH_BYTES) {
                Ok(bytes) => bytes,
                Err(super::FileError::Io(e)) => {
                    return Err(wrap(MeshError {
                        source,
                        line: None,
                        kind: MeshErrorKind::Io {
                            kind: e.kind(),
                            message: e.to_string(),
                        },
                    }));
                }
                Err(e) => return Err(self.invalid("mesh.file", format!("{source} {e}"))),
            };
        // A binary Gmsh file is not UTF-8 past its header: a lossy conversion keeps the
        // header readable, so the reader can say "binary" rather than "not text".
        read_gmsh(&String::from_utf8_lossy(&bytes), &source).map_err(wrap)
    }

    /// The distinct materials and each tetrahedron's material index.
    fn materials(&self, mesh: &TetMesh) -> Result<(Vec<Material>, Vec<u16>), SceneError> {
        let base = Material {
            young_modulus: self.material.young_modulus,
            poisson_ratio: self.material.poisson_ratio,
            density: self.material.density,
        };
        let mut materials = vec![base];
        let mut by_tag = std::collections::HashMap::new();
        for (k, r) in self.material.regions.iter().enumerate() {
            if !mesh.tet_tags.contains(&r.tag) {
                return Err(self.invalid(
                    format!("material.regions[{k}].tag"),
                    format!("no tetrahedron of the mesh has tag {}", r.tag),
                ));
            }
            by_tag.insert(r.tag, materials.len() as u16);
            materials.push(Material {
                young_modulus: r.young_modulus.unwrap_or(base.young_modulus),
                poisson_ratio: r.poisson_ratio.unwrap_or(base.poisson_ratio),
                density: r.density.unwrap_or(base.density),
            });
        }
        let tet_material = mesh
            .tet_tags
            .iter()
            .map(|t| by_tag.get(t).copied().unwrap_or(0))
            .collect();
        Ok((materials, tet_material))
    }

    /// Fixed vertices from `fixed.nodes` and `fixed.boxes`, sorted and unique.
    fn fixed_vertices(&self, mesh: &TetMesh) -> Result<Vec<u32>, SceneError> {
        let n = mesh.vertex_count();
        let mut fixed = Vec::new();
        for (k, &i) in self.fixed.nodes.iter().enumerate() {
            if i as usize >= n {
                return Err(self.invalid(
                    format!("fixed.nodes[{k}]"),
                    format!("vertex {i} does not exist (the mesh has {n}, numbered from 0 in file order)"),
                ));
            }
            fixed.push(i);
        }
        for (k, b) in self.fixed.boxes.iter().enumerate() {
            let before = fixed.len();
            let candidates: Box<dyn Iterator<Item = u32>> = if self.fixed.surface_only {
                Box::new(mesh.surface.vertices.iter().copied())
            } else {
                Box::new(0..n as u32)
            };
            for i in candidates {
                let p = mesh.positions[i as usize];
                if (0..3).all(|a| b.min[a] <= p[a] && p[a] <= b.max[a]) {
                    fixed.push(i);
                }
            }
            if fixed.len() == before {
                return Err(self.invalid(
                    format!("fixed.boxes[{k}]"),
                    "contains no vertex of the mesh",
                ));
            }
        }
        fixed.sort_unstable();
        fixed.dedup();
        Ok(fixed)
    }
}

/// Whether holding `fixed` removes every rigid motion: three fixed vertices not on one
/// line. "On one line" is judged relative to the spread of the set, so the test does not
/// depend on units.
fn removes_rigid_motion(positions: &[Point3<f64>], fixed: &[u32]) -> bool {
    let Some(&a) = fixed.first() else {
        return false;
    };
    let a = positions[a as usize];
    let Some(far) = fixed
        .iter()
        .map(|&i| positions[i as usize] - a)
        .max_by(|p, q| p.norm().total_cmp(&q.norm()))
    else {
        return false;
    };
    let len = far.norm();
    if len == 0.0 {
        return false;
    }
    let axis = far / len;
    fixed.iter().any(|&i| {
        let d = positions[i as usize] - a;
        (d - axis * d.dot(&axis)).norm() > 1e-6 * len
    })
}

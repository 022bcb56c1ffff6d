//! Time integration of the elastic liver: explicit (symplectic Euler with automatic
//! substeps), implicit (backward Euler solved by conjugate gradient) and static
//! (the equilibrium `K u = f` of the current constraints).
//!
//! All three advance a [`State`] by one mechanics tick of length `dt`, honour the
//! vertices whose positions are imposed ([`Imposed`]: fixed nodes, and later the
//! vertices an instrument holds), and leave in [`State::reaction`] the internal elastic
//! force on each imposed vertex — the tissue's reaction, `−(K u)_i`.
//!
//! Every buffer is allocated when the integrator is built; a step allocates nothing.
//!
//! The steps walk several per-vertex arrays (positions, velocities, masses, masks)
//! in lock-step; indexing them by vertex reads better than zipping five iterators.
#![allow(clippy::needless_range_loop)]

pub mod amg;
mod cg;
mod energy;
mod explicit;
mod implicit;
mod imposed;
mod interrupt;
mod preconditioner;
mod statics;
mod storage;

pub use cg::{CgReport, CgWorkspace, Stop};
pub use energy::{kinetic_energy, mechanical_energy};
pub use imposed::Imposed;
pub use interrupt::Interrupt;
pub use preconditioner::{AUTO_AMG_VERTICES, PreconditionerKind};
pub use storage::{F32_FROM_BYTES, StiffnessStorage};

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};

use super::elastic::{BlockMatrix, Corotated, ElasticModel, Parts, TANGENT_TURN, part_count};
use super::workers::Workers;

/// The deformable body's state.
#[derive(Clone, Debug)]
pub struct State {
    /// Current vertex positions `x_i`, m.
    pub x: Vec<Point3<f64>>,
    /// Current vertex velocities `v_i`, m/s.
    pub v: Vec<Vector3<f64>>,
    /// The internal elastic force on each imposed vertex after the last step,
    /// `−(K u)_i` (N); zero on free vertices. It is the force the tissue exerts on
    /// whatever holds the vertex in place.
    pub reaction: Vec<Vector3<f64>>,
}

impl State {
    /// The body at rest in its reference configuration.
    pub fn at_rest(model: &ElasticModel) -> Self {
        let n = model.vertex_count();
        State {
            x: model.rest.clone(),
            v: vec![Vector3::zeros(); n],
            reaction: vec![Vector3::zeros(); n],
        }
    }

    /// Displacements `u_i = x_i − X_i` written into `out`.
    pub fn displacement_into(&self, model: &ElasticModel, out: &mut [Vector3<f64>]) {
        for ((o, x), r) in out.iter_mut().zip(&self.x).zip(&model.rest) {
            *o = x - r;
        }
    }
}

/// Which integrator a scene uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum IntegratorKind {
    Explicit,
    Implicit,
    Static,
}

/// Integrator settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IntegratorConfig {
    pub kind: IntegratorKind,
    /// Mass-proportional (Rayleigh) damping coefficient α, 1/s: the damping force on
    /// vertex `i` is `−α m_i v_i`. Every underdamped mode decays as `e^{−αt/2}`.
    pub damping: f64,
    /// Conjugate-gradient stopping tolerance, relative to the size of the forces that
    /// form the right-hand side (see [`implicit`] and [`statics`]).
    pub cg_tolerance: f64,
    /// Conjugate-gradient iteration cap per solve.
    pub cg_max_iterations: u32,
    /// The conjugate-gradient preconditioner (implicit and static).
    pub preconditioner: PreconditionerKind,
    /// Explicit substeps are `h ≤ safety · 2/ω̂`, where `ω̂² ≥ ω_max²` is the
    /// Gershgorin bound of [`ElasticModel::max_eigenvalue_bound`]. Symplectic Euler is
    /// stable for `h ω_max < 2`; the bound already over-estimates `ω_max`, and the 0.9
    /// default keeps a margin for round-off.
    pub explicit_safety: f64,
    /// Threads the implicit solve shares its products, vector updates and
    /// corotational update with, the calling thread included (see [`Workers`]): the
    /// mesh is split into [`part_count`] parts, fewer than `threads` if small.
    pub threads: usize,
    /// The precision the implicit solve reads the stiffness blocks in (see
    /// [`StiffnessStorage`]).
    pub storage: StiffnessStorage,
}

impl Default for IntegratorConfig {
    fn default() -> Self {
        IntegratorConfig {
            kind: IntegratorKind::Implicit,
            damping: 10.0,
            cg_tolerance: 1e-4,
            cg_max_iterations: 1000,
            preconditioner: PreconditionerKind::default(),
            explicit_safety: 0.9,
            threads: 1,
            storage: StiffnessStorage::default(),
        }
    }
}

/// What one step did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepReport {
    /// Explicit substeps taken (1 for implicit and static); fewer than needed when the
    /// step was interrupted.
    pub substeps: u32,
    /// Conjugate-gradient iterations (0 for explicit).
    pub cg_iterations: u32,
    /// Final relative residual of the solve (0 for explicit).
    pub relative_residual: f64,
    /// Whether the solve met its tolerance within the iteration cap.
    pub converged: bool,
    /// What ended a solve that did not converge (`None` when it did, and for
    /// explicit steps).
    pub stopped_by: Option<SolveLimit>,
}

/// What ended a solve before its tolerance.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SolveLimit {
    /// A linear solve reached `mechanics.cg_max_iterations`.
    Iterations,
    /// A static solve's linear solves together reached the mesh's budget of CG
    /// iterations ([`max_cg_iterations`](crate::engine::scene::limits::max_cg_iterations)).
    Budget,
    /// A corotational static solve made its most rotation updates (1000).
    RotationUpdates,
    /// The step was interrupted (the session closing, Ctrl-C in a headless run).
    Interrupted,
}

impl std::fmt::Display for SolveLimit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SolveLimit::Iterations => {
                f.write_str("a linear solve reached mechanics.cg_max_iterations")
            }
            SolveLimit::Budget => {
                f.write_str("the solve used its budget of CG iterations for the mesh")
            }
            SolveLimit::RotationUpdates => write!(
                f,
                "the solve made its {} rotation updates",
                statics::MAX_ROTATION_UPDATES
            ),
            SolveLimit::Interrupted => f.write_str("the solve was interrupted"),
        }
    }
}

/// The workers for `parts` parts, the caller included: one a part, but no more than
/// the machine's cores (a session's threads would only take turns on one core, each
/// spinning while it waits), none for one part, and none if they cannot be
/// started. Results depend on the parts, not on how many threads run them, so
/// neither cap changes them.
fn crew(parts: usize) -> Option<Workers> {
    let cores = std::thread::available_parallelism().map_or(1, |c| c.get());
    let running = parts.min(cores);
    if running <= 1 {
        return None;
    }
    Workers::new(running)
        .map_err(|e| tracing::warn!("mechanics runs on one thread: {e}"))
        .ok()
}

/// An integrator with its preallocated workspace.
#[derive(Debug)]
pub struct Integrator {
    config: IntegratorConfig,
    /// Largest stable explicit substep for the model, s.
    explicit_h_max: f64,
    /// Displacement buffer `u`.
    u: Vec<Vector3<f64>>,
    /// Force or right-hand-side buffer.
    f: Vec<Vector3<f64>>,
    /// Scratch buffer.
    w: Vec<Vector3<f64>>,
    /// Start positions of imposed vertices during explicit substeps.
    start: Vec<Point3<f64>>,
    cg: CgWorkspace,
    /// `h` for which the implicit preconditioner was last built (NaN: never).
    preconditioned_for: f64,
    /// Whether solves use multigrid (the configured kind, resolved for the model).
    uses_amg: bool,
    /// The scales `(s_M, s_K)` for which building the hierarchy failed, if any.
    amg_failed: Option<(f64, f64)>,
    /// Raised to end a step early (the state is then partway through the tick).
    interrupt: Interrupt,
    /// The rotations, rotated stiffness `K̂` and offset `o` of a corotational model
    /// (`None` for a linear one): every `K u` of the linear model reads `K̂ u + o`.
    corotated: Option<Corotated>,
    /// The turn below which the implicit and explicit steps keep an element's share
    /// of `K̂` (rad, [`TANGENT_TURN`] unless set).
    tangent_turn: f64,
    /// The most CG iterations one static solve makes over all its rotation updates
    /// (the tick-work bound's cap for the mesh, [`max_cg_iterations`], unless set):
    /// see [`statics`].
    ///
    /// [`max_cg_iterations`]: crate::engine::scene::limits::max_cg_iterations
    static_budget: u32,
    /// The threads of [`IntegratorConfig::threads`] besides the caller's (`None`
    /// for one thread).
    workers: Option<Workers>,
    /// The vertices and elements split among them (one part for one thread).
    parts: Parts,
    /// The stiffness blocks rounded to f32, which the implicit solve's products
    /// read when [`IntegratorConfig::storage`] says so (empty otherwise): the
    /// linear `K`'s once, the corotational `K̂`'s each tick.
    blocks32: Vec<nalgebra::Matrix3<f32>>,
}

impl Integrator {
    /// Builds an integrator for `model`, allocating every buffer a step will need.
    pub fn new(config: IntegratorConfig, model: &ElasticModel) -> Self {
        let n = model.vertex_count();
        let explicit_h_max = config.explicit_safety * 2.0 / model.max_eigenvalue_bound().sqrt();
        let count = part_count(model.vertex_count(), config.threads);
        let parts = Parts::new(
            model.vertex_count(),
            count,
            model.elements.iter().map(|e| e.tet),
        );
        let mut cg = CgWorkspace::new(n);
        cg.set_parts(parts.clone());
        let mut corotated = model.corotated();
        if let Some(c) = &mut corotated {
            c.set_parts(parts.clone());
        }
        let blocks = model.stiffness.block.len();
        let mut blocks32 = Vec::new();
        if config.kind == IntegratorKind::Implicit && config.storage.uses_f32(blocks) {
            // The linear K never changes: rounded once. K̂ is rounded each tick.
            blocks32 = model.stiffness.block.iter().map(|b| b.cast()).collect();
        }
        Integrator {
            config,
            explicit_h_max,
            u: vec![Vector3::zeros(); n],
            f: vec![Vector3::zeros(); n],
            w: vec![Vector3::zeros(); n],
            start: vec![Point3::origin(); n],
            cg,
            preconditioned_for: f64::NAN,
            uses_amg: config.preconditioner.uses_amg(n, count),
            amg_failed: None,
            interrupt: Interrupt::default(),
            corotated,
            tangent_turn: TANGENT_TURN,
            static_budget: crate::engine::scene::limits::max_cg_iterations(n),
            workers: crew(count),
            parts,
            blocks32,
        }
    }

    /// Whether the implicit solve reads the stiffness in f32 (see
    /// [`StiffnessStorage`]).
    pub fn reads_f32(&self) -> bool {
        !self.blocks32.is_empty()
    }

    /// Corotational: extracts the rotations at `x`, keeps the force there and brings
    /// `K̂` to within [`TANGENT_TURN`] of them (for the substeps of a tick); nothing
    /// for a linear model.
    fn freeze_rotations(&mut self, model: &ElasticModel, x: &[Point3<f64>]) {
        if let Some(c) = &mut self.corotated {
            c.update_shared(
                model,
                x,
                &mut self.f,
                self.tangent_turn,
                self.workers.as_ref(),
            );
        }
    }

    /// Sets the turn (rad, at least 0; [`TANGENT_TURN`] by default) below which the
    /// implicit and explicit steps keep an element's share of the corotational
    /// tangent `K̂`: 0 reassembles all of it every step.
    /// Static solves always reassemble all of it.
    pub fn set_tangent_turn(&mut self, turn: f64) {
        self.tangent_turn = turn.max(0.0);
    }

    /// Sets the most CG iterations a static solve makes over all its rotation
    /// updates, for tests: a scene cannot raise it past the tick-work bound's cap
    /// for its mesh, the default.
    pub fn set_static_budget(&mut self, iterations: u32) {
        self.static_budget = iterations;
    }

    /// How many elements' shares of the corotational tangent the last step
    /// assembled (0 for a linear model).
    pub fn tangent_reassembled(&self) -> usize {
        self.corotated.as_ref().map_or(0, Corotated::reassembled)
    }

    /// `f = K u` (linear) or `f = Σ_e R_e K_e (R_eᵀ x_e − X_e)` with the rotations
    /// extracted at `x` (corotational): the negated elastic force at `x`, N.
    fn exact_negated_elastic_force(&mut self, model: &ElasticModel, x: &[Point3<f64>]) {
        match &mut self.corotated {
            Some(c) => c.force_shared(model, x, &mut self.f, self.workers.as_ref()),
            None => {
                for ((u, x), r) in self.u.iter_mut().zip(x).zip(&model.rest) {
                    *u = x - r;
                }
                model.stiffness.mul(&self.u, &mut self.f);
            }
        }
    }

    /// The stiffness the last step moved the liver with: the corotational tangent
    /// `K̂ = Σ_e R_e K_e R_eᵀ` with the tick's rotations, or the model's linear `K`.
    /// What a correction made after the step must use to stay consistent with it.
    pub fn tangent<'a>(&'a self, model: &'a ElasticModel) -> &'a BlockMatrix {
        self.corotated
            .as_ref()
            .map_or(&model.stiffness, |c| &c.tangent)
    }

    /// The rotation of element `e` as the last step left it (identity for a linear
    /// model), for tests and inspection.
    pub fn element_rotation(&self, e: usize) -> nalgebra::Matrix3<f64> {
        self.corotated
            .as_ref()
            .map_or_else(nalgebra::Matrix3::identity, |c| c.rotation(e))
    }

    /// Makes every later step stop between substeps or CG iterations once `flag` is
    /// raised, leaving the state partway through the tick (for a session that is
    /// closing, so that closing never waits for a long tick).
    pub fn set_interrupt(&mut self, flag: Arc<AtomicBool>) {
        self.interrupt = Interrupt::new(flag);
        self.cg.interrupt = self.interrupt.clone();
    }

    /// Into how many parts the mesh is split for threads ([`part_count`]).
    pub fn parts(&self) -> usize {
        self.parts.count()
    }

    /// The settings.
    pub fn config(&self) -> &IntegratorConfig {
        &self.config
    }

    /// The explicit substeps a tick of `dt` seconds needs: `⌈dt / h_max⌉` (saturating;
    /// scenes are checked against [`explicit_substeps_f64`](Self::explicit_substeps_f64)).
    pub fn explicit_substeps(&self, dt: f64) -> u32 {
        self.explicit_substeps_f64(dt) as u32
    }

    /// `⌈dt / h_max⌉` in f64, so that a vanishing stable step shows as a huge (or
    /// infinite) count rather than a wrapped one.
    pub fn explicit_substeps_f64(&self, dt: f64) -> f64 {
        (dt / self.explicit_h_max).ceil().max(1.0)
    }

    /// The largest stable explicit substep `h_max` for the model, s.
    pub fn explicit_step_max(&self) -> f64 {
        self.explicit_h_max
    }

    /// Advances `state` by one tick of `dt` seconds (`dt > 0`) under gravity `g`
    /// (m/s²), with the imposed vertices moved to their targets by the end of the tick.
    pub fn step(
        &mut self,
        model: &ElasticModel,
        state: &mut State,
        imposed: &Imposed,
        gravity: Vector3<f64>,
        dt: f64,
    ) -> StepReport {
        debug_assert!(dt > 0.0 && dt.is_finite());
        let report = match self.config.kind {
            IntegratorKind::Explicit => explicit::step(self, model, state, imposed, gravity, dt),
            IntegratorKind::Implicit => implicit::step(self, model, state, imposed, gravity, dt),
            IntegratorKind::Static => statics::solve(self, model, state, imposed, gravity),
        };
        self.update_reaction(model, state, imposed);
        report
    }

    /// Solves for the static equilibrium of the current constraints, whatever the
    /// configured kind: the reference that dynamic runs settle to.
    pub fn solve_static(
        &mut self,
        model: &ElasticModel,
        state: &mut State,
        imposed: &Imposed,
        gravity: Vector3<f64>,
    ) -> StepReport {
        let report = statics::solve(self, model, state, imposed, gravity);
        self.update_reaction(model, state, imposed);
        report
    }

    /// `reaction_i = −(K u)_i` on imposed vertices, zero elsewhere.
    ///
    /// Corotational: `−(K̂ u + o)_i`, with the rotations the implicit or static solve
    /// used (frozen over the tick: the operator it solved with), or those of the end
    /// of an explicit step.
    fn update_reaction(&mut self, model: &ElasticModel, state: &mut State, imposed: &Imposed) {
        state.displacement_into(model, &mut self.u);
        state
            .reaction
            .iter_mut()
            .for_each(|r| *r = Vector3::zeros());
        for &i in imposed.list() {
            let i = i as usize;
            state.reaction[i] = -match &self.corotated {
                Some(c) => c.row(i, &state.x),
                None => model.stiffness.row_times(i, &self.u),
            };
        }
    }

    /// Bytes of workspace held (for memory reports).
    pub fn heap_bytes(&self) -> usize {
        (self.u.capacity() + self.f.capacity() + self.w.capacity()) * 24
            + self.start.capacity() * 24
            + self.cg.heap_bytes()
            + self.corotated.as_ref().map_or(0, Corotated::heap_bytes)
            + self.parts.heap_bytes()
            + self.blocks32.capacity() * std::mem::size_of::<nalgebra::Matrix3<f32>>()
    }
}

#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_amg;
#[cfg(test)]
mod tests_corotational;
#[cfg(test)]
mod tests_interrupt;

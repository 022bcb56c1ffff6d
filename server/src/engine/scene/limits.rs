//! The ranges a scene is held to, so that a scene that passes its checks keeps every
//! tick finite in value and in time.
//!
//! **Finite values.** With `n ≤ 10⁶` vertices (a 32 MiB mesh, [`super::MAX_MESH_BYTES`],
//! has about 2·10⁵), the largest numbers a tick forms are bounded as follows. A
//! tetrahedron's stiffness blocks are `K ~ (λ + 2μ) V / L²`, at most `(λ + 2μ) L` with
//! `L` its longest edge. With `ν ≤` [`MAX_POISSON_RATIO`], `λ = Eν/((1+ν)(1−2ν)) ≤ 167 E`
//! and `λ + 2μ ≤ 168 E`; with `E ≤` [`MAX_YOUNG_MODULUS_PA`] and `L ≤ 2 ·`
//! [`MAX_COORDINATE_M`], a block is below `168 · 10¹² · 200 ≈ 3·10¹⁶` N/m, a vertex's row
//! (a few dozen blocks) below `10¹⁸`, a force `K u` below `10²⁰` N, and the
//! conjugate-gradient dot products over `n` vertices below `10⁴⁶`. Masses are at most
//! `ρ V ≤ 10⁵ · 10⁷` kg, gravity loads `≤ 10³ ·` that, damping multiplies a mass by at
//! most `1 + h α ≤ 10⁴`. Every product stays below `10⁵⁰`, far from f64's `1.8·10³⁰⁸`.
//! From below, the conjugate gradient stops once its residual has vanished into
//! subnormal numbers (see `integrate::cg`), and a tolerance under
//! [`MIN_CG_TOLERANCE`] is refused, so no division by an underflowed quantity happens.
//!
//! **Finite time.** The work of one tick is bounded by [`MAX_TICK_WORK`]; the
//! integrator also stops between substeps or iterations when its session closes.

use laparo_proto::text::Number;

use super::{Scene, SceneError};
use crate::engine::integrate::{Integrator, IntegratorKind};
use crate::engine::mesh::TetMesh;

/// Stiffest material, Pa: 10¹² Pa, five times steel (2·10¹¹ Pa). Liver is a few kPa.
pub const MAX_YOUNG_MODULUS_PA: f64 = 1e12;
/// Softest material, Pa: 1 Pa, a thousand times softer than brain or fat (~1 kPa).
pub const MIN_YOUNG_MODULUS_PA: f64 = 1.0;
/// Largest Poisson ratio: 0.499. λ/μ = 2ν/(1−2ν) grows without bound as ν → 0.5; at
/// 0.499 it is 499, which keeps `λ ≤ 167 E` (see the module notes). Tissue is modelled
/// at 0.45–0.49.
pub const MAX_POISSON_RATIO: f64 = 0.499;
/// Lightest material, kg/m³: 0.01, a hundred times lighter than air.
pub const MIN_DENSITY: f64 = 1e-2;
/// Densest material, kg/m³: 10⁵, four times osmium (2.26·10⁴).
pub const MAX_DENSITY: f64 = 1e5;
/// Largest coordinate of the scaled mesh, of a trocar or of a fixed box, m: 100 m. An
/// operating field is under a metre; 100 m still admits a mesh left in SOFA's units
/// (about 6.5 "metres" across) and bounds every length a tick forms.
pub const MAX_COORDINATE_M: f64 = 100.0;

/// Whether a coordinate is out of any physical place: not finite, or beyond
/// ±[`MAX_COORDINATE_M`]. A mesh is refused unless it lies within that range, so tissue
/// found beyond it was thrown there by the simulation; both a served session
/// (`session/halt.rs`) and a headless run stop on it.
pub fn out_of_place(c: f64) -> bool {
    !c.is_finite() || c.abs() > MAX_COORDINATE_M
}
/// Smallest size (bounding-box diagonal) of the scaled mesh, m: 1 mm. A smaller body is
/// a scale mistake, and its volumes (`L³`) head for underflow.
pub const MIN_MESH_SIZE_M: f64 = 1e-3;
/// Largest gravity component, m/s²: 1000, about a hundred g.
pub const MAX_GRAVITY: f64 = 1e3;
/// Largest mass damping α, 1/s: 10⁴ stops any motion within a millisecond.
pub const MAX_DAMPING: f64 = 1e4;
/// Smallest relative conjugate-gradient tolerance: 10⁻¹². f64 carries 16 digits and
/// the residual of an assembled stiffness stalls a few digits above that; asking for
/// less only runs every tick to its iteration cap.
pub const MIN_CG_TOLERANCE: f64 = 1e-12;
/// Largest CG iteration cap a scene may give, whatever its mesh: 10⁵. The per-tick
/// work bound [`MAX_TICK_WORK`] then applies to the cap times the mesh's vertices.
pub const MAX_CG_ITERATIONS: u32 = 100_000;
/// Longest name of a scene or of one of its instruments, bytes of UTF-8: 256, what a
/// client may send for either ([`service::limits::MAX_NAME_BYTES`] is this), so that
/// every scene a server lists can be asked for and every instrument claimed. A
/// longer one loaded, was listed as available, and every `CreateSession` naming it
/// was refused.
///
/// [`service::limits::MAX_NAME_BYTES`]: crate::service::limits::MAX_NAME_BYTES
pub const MAX_NAME_BYTES: usize = 256;
/// Largest instrument radius, m: 0.1. Laparoscopic instruments are 3–12 mm across.
pub const MAX_INSTRUMENT_RADIUS_M: f64 = 0.1;
/// Largest instrument length inside the body, m: 2. Instruments are 0.3–0.45 m long.
pub const MAX_INSTRUMENT_LENGTH_M: f64 = 2.0;
/// Largest friction coefficient: 10 (rubber on dry rubber is about 1–2).
pub const MAX_FRICTION: f64 = 10.0;

/// Most work one tick may do, in vertex-iterations: explicit substeps, or
/// conjugate-gradient iterations at the scene's cap, times the mesh's vertices.
///
/// The unit is one stiffness product's work on one vertex. A linear explicit substep
/// or a block-Jacobi CG iteration costs about one product and a few vector updates:
/// about 60 ns per vertex on the project's 2-core machine (liver-300k, 60 307
/// vertices: 3.5 ms an explicit substep, 3.7 ms a CG iteration), so such a tick at the
/// bound takes at most about 6 s whatever the mesh. Two kinds of step cost more per
/// unit, and the bound counts them as units all the same, so that every scene in the
/// stability grid stays admissible: a corotational explicit substep re-extracts every
/// element's rotation (liver-300k: 81 ms, about 1.3 µs per vertex, 22 products), and a
/// multigrid-preconditioned CG iteration runs a V-cycle (liver-300k: about 30 ms, 8
/// products). At the bound, ticks of those kinds take up to about 130 s and 50 s. The
/// integrator stops between substeps or iterations when its session closes, so even
/// those never hold up a shutdown. The scenes in use are far below (the default
/// scene's worst case is 181 vertices × 1000 iterations, 1.8·10⁵; liver-300k at 1000
/// CG iterations is 6·10⁷; liver-5k explicit at 10 MPa and 20 Hz is 4.5·10⁷). A scene
/// over the bound would leave its session unable to keep time for minutes or, with a
/// vanishing stable step, for ever.
pub const MAX_TICK_WORK: f64 = 1e8;

/// The largest CG iteration cap a mesh of `vertices` vertices may have: the tick-work
/// bound over the vertices, at most [`MAX_CG_ITERATIONS`] (at least 1).
pub fn max_cg_iterations(vertices: usize) -> u32 {
    (MAX_TICK_WORK / vertices.max(1) as f64)
        .floor()
        .clamp(1.0, f64::from(MAX_CG_ITERATIONS)) as u32
}

impl Scene {
    /// The scaled and centred mesh stays within [`MAX_COORDINATE_M`] and is at least
    /// [`MIN_MESH_SIZE_M`] across.
    pub(crate) fn check_mesh_extent(&self, mesh: &TetMesh) -> Result<(), SceneError> {
        let (lo, hi) = mesh.bounding_box();
        let far = lo.coords.amax().max(hi.coords.amax());
        if !(far.is_finite() && far <= MAX_COORDINATE_M) {
            return Err(self.invalid(
                "mesh.scale",
                format!(
                    "the scaled mesh reaches {} m from the origin; at most \
                     {MAX_COORDINATE_M} m: check mesh.scale (metres per mesh unit) or set \
                     mesh.center",
                    Number(far)
                ),
            ));
        }
        let size = (hi - lo).norm();
        if !(size.is_finite() && size >= MIN_MESH_SIZE_M) {
            return Err(self.invalid(
                "mesh.scale",
                format!(
                    "the scaled mesh is {} m across; at least {MIN_MESH_SIZE_M} m: \
                     check mesh.scale (metres per mesh unit)",
                    Number(size)
                ),
            ));
        }
        Ok(())
    }

    /// The work of one tick stays within [`MAX_TICK_WORK`]: the explicit integrator's
    /// substeps (from its stable step on this mesh and material), or the CG iteration
    /// cap, times the vertices.
    pub(crate) fn check_tick_work(
        &self,
        integrator: &Integrator,
        vertices: usize,
        dt: f64,
    ) -> Result<(), SceneError> {
        let n = vertices as f64;
        let config = integrator.config();
        if config.kind == IntegratorKind::Explicit {
            let substeps = integrator.explicit_substeps_f64(dt);
            if !(substeps.is_finite() && substeps * n <= MAX_TICK_WORK) {
                return Err(self.invalid(
                    "mechanics.integrator",
                    format!(
                        "the explicit integrator needs {substeps:.3e} substeps a tick \
                         (its stable step on this mesh and material is {:.3e} s, a tick \
                         is {dt:.3e} s); with {vertices} vertices that is {:.3e} \
                         vertex-substeps, over the limit of {MAX_TICK_WORK:e} a tick, so \
                         the session could not keep time or close. Use the implicit \
                         integrator, raise mechanics.rate_hz, or check material.density \
                         (light material needs tiny steps) and material.young_modulus",
                        integrator.explicit_step_max(),
                        substeps * n
                    ),
                ));
            }
        } else {
            let work = f64::from(config.cg_max_iterations) * n;
            if !(work.is_finite() && work <= MAX_TICK_WORK) {
                return Err(self.invalid(
                    "mechanics.cg_max_iterations",
                    format!(
                        "{} CG iterations a tick on {vertices} vertices is {work:.3e} \
                         vertex-iterations, over the limit of {MAX_TICK_WORK:e} a tick, so \
                         a tick could take minutes: at most {} iterations on this mesh",
                        config.cg_max_iterations,
                        max_cg_iterations(vertices)
                    ),
                ));
            }
        }
        Ok(())
    }
}

//! Which preconditioner the implicit and static solves use, and when the multigrid
//! hierarchy is built.
//!
//! Block Jacobi costs nothing to set up and little per iteration, but its iterations
//! grow with the mesh; smoothed-aggregation multigrid ([`amg`](super::amg)) costs a
//! setup and several products per iteration, and its iterations stay nearly flat.
//! `auto` (the default) takes multigrid from [`AUTO_AMG_VERTICES`] vertices up, on
//! one thread.
//!
//! A multigrid iteration costs about five products of the fine matrix where block
//! Jacobi's costs one, so the scene limit on a tick's work (CG iteration cap times
//! vertices, [`MAX_TICK_WORK`](crate::engine::scene::limits::MAX_TICK_WORK)) bounds
//! a multigrid tick that never converges about five times more loosely; such a tick
//! still stops between iterations when its session closes.

use serde::{Deserialize, Serialize};

use super::amg::Amg;
use super::{Integrator, IntegratorKind};
use crate::engine::elastic::ElasticModel;

/// A scene's `[mechanics] preconditioner`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PreconditionerKind {
    /// Multigrid from [`AUTO_AMG_VERTICES`] vertices up on one thread, block Jacobi
    /// below and whenever the mesh is split among threads (see [`AUTO_AMG_VERTICES`]).
    #[default]
    Auto,
    /// Inverse 3×3 diagonal blocks.
    BlockJacobi,
    /// Smoothed-aggregation algebraic multigrid, one V-cycle per iteration.
    Amg,
}

/// Meshes with at least this many vertices use multigrid under `auto`. Measured
/// with the bench `step` (implicit, 60 Hz, tolerance 1e-4, one core, a loaded
/// machine): multigrid cuts the iterations a tick from 6, 10, 16, 27 and 195 to 2,
/// 2, 3, 4 and 14 from SOFA's liver (181 vertices) to liver-300k (60k), and the
/// linear tick from 0.50 to 0.33 ms on liver-5k (1,408 vertices), 6.7 to 5.2 ms on
/// liver-20k and 40 to 31 ms on liver-80k; the corotational tick, dominated by its
/// rotation update at these sizes, is about the same either way. On SOFA's liver the
/// two are within a few microseconds of each other, and block Jacobi keeps the
/// behaviour the haptic tests were tuned with.
///
/// On several threads block Jacobi is taken at every size: all of its work is
/// shared by the parts, while the multigrid cycle's coarse levels run on one
/// thread. Measured (corotational bench, contact, kept tangent, 2 threads, one run):
/// block Jacobi 4.24 / 23.5 / 132 ms a tick on liver-20k / 80k / 300k, multigrid
/// 6.29 / 34.7 / 298 ms.
pub const AUTO_AMG_VERTICES: usize = 1000;

impl PreconditionerKind {
    /// Whether a model of `vertices` vertices, split into `parts` parts for threads
    /// ([`part_count`](crate::engine::elastic::part_count)), is solved with multigrid.
    pub fn uses_amg(self, vertices: usize, parts: usize) -> bool {
        match self {
            PreconditionerKind::Auto => parts == 1 && vertices >= AUTO_AMG_VERTICES,
            PreconditionerKind::BlockJacobi => false,
            PreconditionerKind::Amg => true,
        }
    }
}

impl Integrator {
    /// The rest system matrix's scales `(s_M, s_K)` for ticks of `dt` seconds:
    /// `((1 + dt·α), dt²)` implicit, `(0, 1)` static, `None` explicit.
    fn system_scales(&self, dt: f64) -> Option<(f64, f64)> {
        match self.config.kind {
            IntegratorKind::Explicit => None,
            IntegratorKind::Implicit => Some((1.0 + dt * self.config.damping, dt * dt)),
            IntegratorKind::Static => Some((0.0, 1.0)),
        }
    }

    /// Builds what the configured preconditioner needs for ticks of `dt` seconds, with
    /// the vertices `supports[i]` held for the scene's life: the multigrid hierarchy
    /// of the rest system matrix (nothing for block Jacobi or an explicit
    /// integrator). A scene calls it when it is built, so that its ticks never do;
    /// a solve for another tick length builds again (see
    /// [`select_preconditioner`](Self::select_preconditioner)).
    pub fn prepare(&mut self, model: &ElasticModel, supports: &[bool], dt: f64) {
        if let Some((s_m, s_k)) = self.system_scales(dt) {
            self.select_preconditioner(model, supports, s_m, s_k);
        }
    }

    /// Chooses the preconditioner of the next solves of `s_M M + s_K K`. With
    /// multigrid, builds the hierarchy unless one exists for these scales (or its
    /// build failed for them: block Jacobi then, with a warning once), the `imposed`
    /// vertices left out of it. Allocates only when it builds.
    pub(super) fn select_preconditioner(
        &mut self,
        model: &ElasticModel,
        imposed: &[bool],
        s_m: f64,
        s_k: f64,
    ) {
        self.cg.use_amg = false;
        if !self.uses_amg {
            return;
        }
        let scales = (s_m, s_k);
        if self.cg.amg.as_ref().map(Amg::scales) == Some(scales) {
            self.cg.use_amg = true;
            return;
        }
        if self.amg_failed == Some(scales) {
            return;
        }
        self.cg.amg = None;
        match Amg::new(
            &model.stiffness,
            &model.mass,
            s_m,
            s_k,
            imposed,
            &model.rest,
        ) {
            Ok(mut amg) => {
                // In the precision of the implicit solve's other matrices (see
                // `StiffnessStorage`), decided on the hierarchy's own size.
                if self.config.kind == IntegratorKind::Implicit
                    && self.config.storage.rounds(amg.matrix_bytes())
                {
                    amg.round_to_f32();
                }
                self.cg.amg = Some(amg);
                self.cg.use_amg = true;
            }
            Err(e) => {
                tracing::warn!("multigrid preconditioner unavailable, using block Jacobi: {e}");
                self.amg_failed = Some(scales);
            }
        }
    }

    /// The multigrid hierarchy, if one is built.
    pub fn amg(&self) -> Option<&Amg> {
        self.cg.amg.as_ref()
    }

    /// Whether the last solve was preconditioned by multigrid.
    pub fn used_amg(&self) -> bool {
        self.cg.use_amg
    }
}

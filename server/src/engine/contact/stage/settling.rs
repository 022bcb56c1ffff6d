//! Around the jumps of the contact steps: the free tissue settled with them, then
//! what the settled tissue pulls away let go and the tissue relaxed around it (the
//! solves themselves are `settle`'s), with the bounds of both.

use nalgebra::Vector3;

use super::ContactStage;
use super::holding::let_go;
use crate::engine::contact::hold::{adhesion, contact_normal, pulled_away};
use crate::engine::contact::instrument::Instrument;
use crate::engine::contact::settle::RINGS;
use crate::engine::elastic::{BlockMatrix, ElasticModel, Formulation};
use crate::engine::integrate::{Imposed, State};
use crate::engine::mesh::Surface;

impl ContactStage {
    /// Settles the free tissue around the held vertices the contact steps jumped this
    /// tick (see `settle`), when the largest jump exceeds [`SETTLE_JUMP`] of the
    /// smallest radius, unless the scene turns it off, each jump scaled down so that
    /// the largest sideways part (across its instrument's axis) is at most
    /// [`SETTLE_REACH`] radii; the region grows by a ring for every radius the largest
    /// settled jump passes one radius by, up to [`SETTLE_RINGS`]. Past a radius, on
    /// the corotational model and when no jump was scaled down, Newton passes on the
    /// model's own force follow the linear settling (see `settle`); a sweep's scaled
    /// jumps are settled linearly only (with the passes, the whole-liver sweep of
    /// `tests/contact_hard_cases.rs` left a triangle 4.9 mm inside the shaft). Returns
    /// the rings it settled, if it did, and then leaves in `rel_start` the surface as
    /// the settling found it.
    pub(super) fn settle_jumps(
        &mut self,
        instruments: &[Instrument],
        surface: &Surface,
        model: &ElasticModel,
        tangent: &BlockMatrix,
        state: &mut State,
        imposed: &Imposed,
    ) -> Option<Settled> {
        let radius = instruments
            .iter()
            .filter(|i| i.current.is_some())
            .map(|i| i.radius)
            .fold(f64::INFINITY, f64::min);
        let settle = self.settle.as_mut()?;
        self.jumped.clear();
        let (mut largest, mut sideways): (f64, f64) = (0.0, 0.0);
        for &v in &surface.vertices {
            let vi = v as usize;
            let holders = self.holders[vi];
            if holders != 0 && !self.s.fixed[vi] && !settle.taken_back(v) {
                let d = state.x[vi] - self.end[vi];
                if d != Vector3::zeros() {
                    largest = largest.max(d.norm());
                    // The first instrument holding it; a vertex two hold is pressed
                    // sideways by one of them at least, which the bound then counts.
                    let across = instruments[holders.trailing_zeros() as usize]
                        .current
                        .map_or(d, |p| p.across(&d));
                    sideways = sideways.max(across.norm());
                    settle.jump[vi] = d;
                    self.jumped.push(v);
                }
            }
        }
        if largest <= SETTLE_JUMP * radius {
            for &v in &self.jumped {
                settle.jump[v as usize] = Vector3::zeros();
            }
            return None;
        }
        let scale = (SETTLE_REACH * radius / sideways).min(1.0);
        if scale < 1.0 {
            for &v in &self.jumped {
                settle.jump[v as usize] *= scale;
            }
        }
        let beyond = (largest * scale / radius - 1.0).max(0.0).ceil() as usize;
        let rings = (RINGS + beyond).min(SETTLE_RINGS);
        // Where the settling starts from: its moves are motion, which the final
        // rounds analyse as such.
        for &v in &surface.vertices {
            self.s.rel_start[v as usize] = state.x[v as usize];
        }
        let nonlinear =
            (scale == 1.0 && largest > radius && model.formulation == Formulation::Corotational)
                .then_some((model, &self.end[..]));
        settle.settle(
            tangent,
            imposed.mask(),
            &self.jumped,
            rings,
            nonlinear,
            &mut state.x,
        );
        Some(Settled {
            rings,
            past_radius: largest * scale > radius,
        })
    }

    /// After a settling whose largest jump passed the radius: lets go of the held
    /// vertices the contact steps moved this tick and the settled tissue pulls away
    /// from their instrument (the normal part of Coulomb's law, `hold::pulled_away`,
    /// on the model's force at each, with the instrument's adhesion), relaxes the
    /// tissue around them ([`Settle::relax`](crate::engine::contact::settle::Settle::relax), over the settling's `rings`), and again,
    /// up to [`RELEASE_ROUNDS`] times, until none is let go: the held set the contact
    /// steps chose by geometry made unilateral within the tick (see `settle`, "A held
    /// set that pulls").
    pub(super) fn release_pulled(
        &mut self,
        instruments: &mut [Instrument],
        model: &ElasticModel,
        tangent: &BlockMatrix,
        state: &mut State,
        imposed: &mut Imposed,
        rings: usize,
    ) {
        let Some(settle) = &mut self.settle else {
            return;
        };
        for _ in 0..RELEASE_ROUNDS {
            self.released.clear();
            for (k, ins) in instruments.iter_mut().enumerate() {
                let Some(pose) = ins.current else { continue };
                let (length, radius, tip_contact) =
                    (ins.active_length(), ins.radius, ins.tip_contact);
                let x = &state.x;
                // The tissue's reaction on each held vertex, in the order of `held`.
                self.reactions.clear();
                self.reactions.extend(
                    ins.held
                        .iter()
                        .map(|&v| -model.negated_elastic_force_on(v, x)),
                );
                let adhesion = adhesion(self.reactions.iter().map(|f| f.norm()));
                let bit = 1u8 << k;
                let (holders, slide, fixed) = (&mut self.holders, &mut self.slide, &self.s.fixed);
                let (released, end) = (&mut self.released, &self.end);
                let mut reactions = self.reactions.iter();
                ins.held.retain(|&v| {
                    let reaction = reactions.next().expect("one reaction per held vertex");
                    // Only what the contact steps moved this tick: the rest was
                    // judged by the same law after the elastic step.
                    if x[v as usize] == end[v as usize] {
                        return true;
                    }
                    let Some((m, _)) =
                        contact_normal(&x[v as usize], &pose, length, radius, tip_contact)
                    else {
                        return true;
                    };
                    if !pulled_away(-reaction.dot(&m), adhesion) {
                        return true;
                    }
                    if let_go(v, bit, holders, slide, fixed, imposed, Some(&mut *settle)) {
                        released.push(v);
                    }
                    false
                });
            }
            if self.released.is_empty() {
                break;
            }
            settle.relax(
                tangent,
                imposed.mask(),
                &self.released,
                rings,
                model,
                &mut state.x,
            );
        }
    }
}

/// The largest jump of a held vertex, as a fraction of the radius, below which the
/// tissue is not settled around the jumps.
const SETTLE_JUMP: f64 = 1e-3;

/// The largest sideways jump (across the instrument's axis) the tissue is settled
/// around, as a fraction of the smallest radius; larger jumps are settled as if
/// scaled down to it. The settling is a linear static correction. Around the
/// jumps of a whole-liver sweep in one tick, 10 cm across the shaft, it carried the
/// free tissue beside the swept strip 13 mm sideways across the shaft's path, so that
/// the strip's two sides crossed over the shaft (liver-5k, SOFA's liver refined once;
/// `tests/contact_hard_cases.rs`). A sideways jump larger than the instrument is a
/// gross move, which the next elastic steps carry the tissue through.
///
/// A jump along the axis is settled whole: the tip pushing tissue ahead of it into
/// the body, however far in one tick. Scaled down like a sideways one, the 3.5 cm
/// jab of `tests/explicit_chatter.rs` (ν = 0.499) left 1.04 J of strain energy in the
/// tissue around the jump, 25 times the held press's 0.042 J, and reported 78 N on
/// its tick against 2.35 N steady. The implicit step took that energy out by its own
/// dissipation; the explicit step turned it into 0.5 J of ringing that let the
/// tissue go and caught it again with 54–104 N jumps for the rest of the hold.
const SETTLE_REACH: f64 = 1.0;

/// The most rings of free nodes settled around a jump ([`RINGS`] for jumps up to a
/// radius, one more for every further radius). A jump the size of the instrument
/// moves the tissue beside it by as much, which three rings of a coarse mesh (3 cm)
/// cut off: the 3.5 cm jab settled whole within three rings left 0.14 J and rang
/// explicitly (the held set changing 9 times in a second, an 18 N retake); within
/// five rings or more it held steadily (within ten, 0.08 J left). Each three rings
/// take [`MAX_ITERATIONS`](crate::engine::contact::settle::MAX_ITERATIONS) more iterations, so a tick
/// settles with at most four times the usual iterations, over a region up to twelve
/// rings deep (on a fine mesh up to (12/3)³ = 64 times as many nodes; never more than
/// the mesh's). Only ticks whose jumps along the axis pass a radius pay it: a jab,
/// not a press.
const SETTLE_RINGS: usize = 12;

/// What [`ContactStage::settle_jumps`] settled.
#[derive(Clone, Copy, Debug)]
pub(super) struct Settled {
    /// The rings of free nodes around the jumps.
    pub(super) rings: usize,
    /// Whether the largest settled jump passed the instrument's radius.
    pub(super) past_radius: bool,
}

/// Rounds of letting go of what the settled tissue pulls away and relaxing around it
/// ([`ContactStage::release_pulled`]). A relaxation can leave another held vertex
/// pulled: a tip posed 1 cm into tissue of 100 kPa, ν = 0.49, let three go, then
/// one more, then none. Six rounds changed none of the first-pose figures of
/// `tests/contact_first_touch.rs`; each round costs a CG solve over the region, on
/// settled ticks only.
const RELEASE_ROUNDS: usize = 3;

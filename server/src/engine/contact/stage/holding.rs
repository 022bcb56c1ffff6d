//! Holding: the vertices the contact steps moved are held where they are; each one
//! held before sticks, slides or is let go by the law of `hold`.

use nalgebra::{Matrix3, Vector3};

use super::ContactStage;
use crate::engine::contact::hold::{
    Hold, MAX_SLIDE, MIN_SLIDE, adhesion, shaft_press, stays_held, tip_press,
};
use crate::engine::contact::instrument::Instrument;
use crate::engine::contact::settle::Settle;
use crate::engine::elastic::ElasticModel;
use crate::engine::integrate::{Imposed, State};
use crate::engine::mesh::Surface;

impl ContactStage {
    /// Holds the vertices moved for instrument `k`; slides those the tissue drags
    /// harder than friction allows, and releases those it pulls away.
    pub(super) fn hold_and_release(
        &mut self,
        k: usize,
        ins: &mut Instrument,
        surface: &Surface,
        model: &ElasticModel,
        state: &State,
        imposed: &mut Imposed,
    ) {
        let bit = 1u8 << k;
        let pose = ins.current.expect("only instruments in the body hold");
        let length = ins.active_length();
        // Adhesion: a pull-away below a tenth of the mean force on the instrument's
        // held vertices does not release (see `stays_held`).
        let adhesion = adhesion(ins.held.iter().map(|&v| state.reaction[v as usize].norm()));
        let ins_params = (ins.tip_contact, ins.friction, adhesion);
        let radius = ins.radius;
        let holders = &mut self.holders;
        let slide = &mut self.slide;
        let settle = &mut self.settle;
        let s = &self.s;
        ins.held.retain(|&v| {
            let vi = v as usize;
            if s.moved_mark[vi] == s.mark {
                return true;
            }
            let hold = stays_held(
                &state.x[vi],
                &state.reaction[vi],
                &pose,
                (length, radius),
                ins_params,
                || tip_press(surface, v, &pose.tip, radius, &state.x),
                || shaft_press(surface, v, &pose, length, radius, &state.x),
            );
            let keep = match hold {
                Hold::Stick => true,
                Hold::Slip(tangent, excess) => {
                    // Slide along the instrument until the drag is back on the
                    // friction cone: the tissue's pull changes by −K_ii δ, so a step
                    // δ = excess / (t̂·K_ii·t̂) along t̂ takes the excess away (to first
                    // order; the vertex's neighbours do not move with it).
                    // The slide is applied with the next tick's rigid motion, before
                    // the contact steps, so that they keep the surface out of the
                    // instrument as for any other move.
                    // A slide longer than half the radius is no small creep along
                    // the instrument but the tissue tearing away from it: let go.
                    let kii = model.stiffness.get(v, v).unwrap_or_else(Matrix3::zeros);
                    let stiffness = tangent.dot(&(kii * tangent.into_inner()));
                    let step = excess / stiffness;
                    if stiffness > 0.0 && step <= MAX_SLIDE * radius {
                        if step >= MIN_SLIDE * radius {
                            slide[vi] = tangent.into_inner() * step;
                        }
                        true
                    } else {
                        false
                    }
                }
                Hold::Release => false,
            };
            if !keep {
                let_go(v, bit, holders, slide, &s.fixed, imposed, settle.as_mut());
            }
            keep
        });
        self.hold(k, ins, state, imposed);
    }

    /// Holds the vertices moved for instrument `k`, where they are now.
    pub(super) fn hold(
        &mut self,
        k: usize,
        ins: &mut Instrument,
        state: &State,
        imposed: &mut Imposed,
    ) {
        let bit = 1u8 << k;
        for &v in &self.s.moved {
            let vi = v as usize;
            if self.holders[vi] & bit == 0 {
                self.holders[vi] |= bit;
                ins.held.push(v);
            }
            imposed.set(v, state.x[vi]);
        }
    }
}

/// Instrument `bit` lets go of vertex `v`: its slide is dropped, and it is freed
/// unless another instrument holds it or it is a support; `settle`, when given,
/// remembers that it was let go ([`Settle::taken_back`]). Returns whether it was
/// freed.
pub(super) fn let_go(
    v: u32,
    bit: u8,
    holders: &mut [u8],
    slide: &mut [Vector3<f64>],
    fixed: &[bool],
    imposed: &mut Imposed,
    settle: Option<&mut Settle>,
) -> bool {
    let vi = v as usize;
    if let Some(settle) = settle {
        settle.let_go(v);
    }
    slide[vi] = Vector3::zeros();
    holders[vi] &= !bit;
    let freed = holders[vi] == 0 && !fixed[vi];
    if freed {
        imposed.release(v);
    }
    freed
}

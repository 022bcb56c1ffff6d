//! What the stage reports to the force model: the tissue's force on each
//! instrument, and the shaft's neighbouring edges.

use nalgebra::Vector3;

use super::ContactStage;
use crate::engine::contact::hold::contact_normal;
use crate::engine::contact::instrument::Instrument;
use crate::engine::elastic::ElasticModel;
use crate::engine::integrate::State;
use crate::engine::mesh::Surface;

impl ContactStage {
    /// The tissue's force on the instrument: the elastic reactions on what it holds,
    /// from the elastic model's own force (corotational: the rotations around each
    /// held vertex extracted afresh; the linear `K u` would count the turn of tissue
    /// pushed aside as strain, and the calibrated force model would render it). With
    /// the scene's `contact.footprint`, the reactions on the tip's end are scaled to
    /// the tip's own footprint, and those on the shaft's side to the strip the shaft
    /// presses (see `footprint`).
    pub(super) fn report_reaction(
        &self,
        ins: &mut Instrument,
        surface: &Surface,
        model: &ElasticModel,
        state: &State,
    ) {
        let mut total = Vector3::zeros();
        ins.report.held_reactions.clear();
        for &v in &ins.held {
            let ku = model.negated_elastic_force_on(v, &state.x);
            ins.report.held_reactions.push(-ku);
            total -= ku;
        }
        ins.report.reaction = total;
        let Some(pose) = ins.current.filter(|_| self.footprint) else {
            return;
        };
        let (length, radius, tip_contact) = (ins.active_length(), ins.radius, ins.tip_contact);
        let z = pose.axis.into_inner();
        let on_tip = |v: u32| {
            tip_contact
                && contact_normal(&state.x[v as usize], &pose, length, radius, true)
                    .is_some_and(|(m, _)| m == -z)
        };
        let held = &ins.held;
        let report = &mut ins.report;
        let patch = |tip: bool| {
            held.iter()
                .zip(&report.held_reactions)
                .filter(move |(v, _)| on_tip(**v) == tip)
                .map(|(&v, &f)| (v, f))
        };
        // The shaft's side, then the tip's end.
        let scales = [
            crate::engine::contact::footprint::shaft_scale(
                patch(false),
                surface,
                &state.x,
                (&pose.tip, &pose.axis),
                radius,
            ),
            crate::engine::contact::footprint::tip_scale(
                patch(true),
                surface,
                &state.x,
                &pose.axis,
                radius,
            ),
        ];
        if scales.iter().all(|&s| s >= 1.0) {
            return;
        }
        let mut cut_total = Vector3::zeros();
        for (&v, f) in held.iter().zip(report.held_reactions.iter_mut()) {
            let cut = (1.0 - scales[usize::from(on_tip(v))]) * *f;
            *f -= cut;
            cut_total += cut;
        }
        report.reaction -= cut_total;
    }

    /// The shaft's neighbouring edges (§3): candidate edges with a held end that lie
    /// along the shaft, within 1.5 r of it.
    pub(super) fn collect_shaft_edges(
        &self,
        ins: &mut Instrument,
        surface: &Surface,
        state: &State,
    ) {
        let Some(pose) = ins.current else { return };
        if !ins.shaft_contact {
            return;
        }
        for &e in &self.s.edges {
            let [a, b] = surface.edges[e as usize];
            let held = |v: u32| self.holders[v as usize] != 0;
            if held(a) || held(b) {
                let c = crate::engine::contact::closest::closest_edge_axis(
                    &state.x[a as usize],
                    &state.x[b as usize],
                    &pose,
                    ins.length,
                );
                if c.beta > 0.0 && c.distance() <= 1.5 * ins.radius {
                    ins.report.shaft_edges.push(e);
                }
            }
        }
    }
}

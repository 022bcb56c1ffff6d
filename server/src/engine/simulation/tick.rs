//! One mechanics tick, as named stages in the paper's order.

use std::time::Instant;

use super::{Simulation, TickTiming};
use crate::engine::integrate::StepReport;

impl Simulation {
    /// Advances one mechanics tick, in this order:
    ///
    /// 1. [`carry_held_vertices`](Self::carry_held_vertices): the vertices each
    ///    instrument holds follow its rigid motion over the tick (eq. 1), so that the
    ///    elastic step sees them where the instrument put them;
    /// 2. [`elastic_step`](Self::elastic_step): the integrator moves the liver with the
    ///    supports and held vertices imposed — the free motion of §2.2;
    /// 3. [`resolve_contact`](Self::resolve_contact): that free motion is analysed from
    ///    each instrument (§2.3–2.6) and the surface kept out of it; the vertices it
    ///    moved become held for the next tick. It needs the free motion, so it comes
    ///    after the elastic step;
    /// 4. the tick and simulated time advance;
    /// 5. [`local_models`](Self::local_models): each instrument's local model and force
    ///    (§3), from the contact the tick ended with, stamped with the new tick.
    ///
    /// Each stage's wall time goes to [`Simulation::last_timing`].
    pub fn tick(&mut self) -> StepReport {
        let t0 = Instant::now();
        self.carry_held_vertices();
        let t1 = Instant::now();
        let report = self.elastic_step();
        let t2 = Instant::now();
        self.resolve_contact();
        let t3 = Instant::now();
        self.tick += 1;
        self.time += self.dt;
        self.local_models();
        let t4 = Instant::now();
        self.last_timing = TickTiming {
            carry_held_vertices: (t1 - t0).as_secs_f64(),
            elastic_step: (t2 - t1).as_secs_f64(),
            resolve_contact: (t3 - t2).as_secs_f64(),
            local_models: (t4 - t3).as_secs_f64(),
        };
        report
    }

    /// Stage 1 (paper eq. 1): held vertices follow their instrument's rigid motion;
    /// instruments that left the body let go. Nothing without a contact stage.
    fn carry_held_vertices(&mut self) {
        if let Some(contact) = &mut self.contact {
            contact.carry_held_vertices(
                &mut self.instruments,
                &self.mesh.surface,
                &self.state,
                &mut self.imposed,
            );
        }
    }

    /// Stage 2: one step of the integrator, the liver under gravity with its imposed
    /// vertices.
    fn elastic_step(&mut self) -> StepReport {
        self.integrator.step(
            &self.model,
            &mut self.state,
            &self.imposed,
            self.gravity,
            self.dt,
        )
    }

    /// Stage 3 (paper §2.3–2.6): colliding edges, confidence intervals, the tip press
    /// and the push-out for every instrument, then holds and releases; the settling
    /// around the jumps uses the stiffness the elastic step just used.
    fn resolve_contact(&mut self) {
        if let Some(contact) = &mut self.contact {
            contact.resolve_contact(
                &mut self.instruments,
                &self.mesh.surface,
                &self.model,
                self.integrator.tangent(&self.model),
                &mut self.state,
                &mut self.imposed,
                self.dt,
            );
        }
    }

    /// Stage 5 (paper §3): every instrument's local model and force at its pose.
    fn local_models(&mut self) {
        if let Some(forces) = &mut self.forces {
            forces.compute_models_and_forces(
                self.tick,
                self.time,
                &self.instruments,
                &self.mesh.surface,
                &self.state.x,
            );
        }
    }
}

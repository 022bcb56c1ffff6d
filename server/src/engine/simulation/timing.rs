//! Wall time of one tick's stages.

/// Wall time of each stage of the last tick, s, one field a stage of
/// [`Simulation::tick`](super::Simulation::tick): what benchmarks report.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TickTiming {
    /// Held vertices carried along with their instruments (contact stage, before the
    /// elastic step).
    pub carry_held_vertices: f64,
    /// The elastic step (the integrator).
    pub elastic_step: f64,
    /// The contact algorithm of §2.3–2.6, holds and releases (after the elastic step).
    pub resolve_contact: f64,
    /// The local models and forces of §3.
    pub local_models: f64,
}

impl TickTiming {
    /// The contact stage's share of the tick: carrying held vertices and resolving
    /// contact, s.
    pub fn contact(&self) -> f64 {
        self.carry_held_vertices + self.resolve_contact
    }

    /// The whole tick, s.
    pub fn total(&self) -> f64 {
        self.carry_held_vertices + self.elastic_step + self.resolve_contact + self.local_models
    }
}

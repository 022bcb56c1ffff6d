//! A tick's outputs, made in one place: the mechanics thread of a live session, the
//! re-simulation of a recording and the re-simulated replay all call
//! [`TickOutputs::produce`], so what they send and write, and in which order, cannot
//! drift apart.
//!
//! The order is the tick's contact events first (they happened during the step),
//! then its [`Frame`] (the surface, then every instrument's state in scene order). A
//! session publishes and records the events, then hands the frame to its recorder
//! and its streams; a replay sends the events, then the surface, then the states.

use laparo_proto::v1;

use super::Frame;
use super::contacts::ContactWatch;
use super::state::{instrument_state, surface_positions};
use crate::engine::simulation::Simulation;

/// Who held an instrument at a tick: the station, and the sequence number of the
/// pose the tick used. Both absent for an instrument no station has posed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Holder {
    pub station: Option<u64>,
    pub pose_sequence: Option<u64>,
}

/// Makes each tick's outputs; keeps what they depend on from tick to tick (which
/// instruments were in contact).
#[derive(Clone, Debug)]
pub struct TickOutputs {
    contacts: ContactWatch,
}

impl TickOutputs {
    /// For a scene of `instruments` instruments, none in contact yet.
    pub fn new(instruments: usize) -> Self {
        TickOutputs {
            contacts: ContactWatch::new(instruments),
        }
    }

    /// After `sim` has ticked: hands each instrument's contact change to `emit` as an
    /// event (in scene order), then returns the tick's frame. `holder(k)` says who
    /// held instrument `k` at this tick.
    ///
    /// Allocates what the frame and the events hold (the surface, one state per
    /// instrument, an event per contact change) and nothing else.
    pub fn produce(
        &mut self,
        sim: &Simulation,
        holder: impl Fn(usize) -> Holder,
        emit: impl FnMut(v1::Event),
    ) -> Frame {
        self.contacts.update(sim, |k| holder(k).station, emit);
        Frame {
            tick: sim.tick,
            sim_time: sim.time,
            surface: surface_positions(sim),
            instruments: (0..sim.instruments.len())
                .map(|k| {
                    let h = holder(k);
                    instrument_state(sim, k, h.station, h.pose_sequence)
                })
                .collect(),
        }
    }
}

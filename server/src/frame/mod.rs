//! What the server says about a scene and about each of its ticks, in the contract's
//! terms: the layer under both [`crate::session`] (live) and [`crate::recording`]
//! (written, re-simulated, replayed), so that neither has to import the other to
//! know what a tick looks like.
//!
//! - [`description`]: the scene as a station first sees it (summary, rest surface,
//!   instruments, gravity).
//! - [`state`]: one tick's surface positions and instrument states, read off a
//!   [`Simulation`](crate::engine::simulation::Simulation).
//! - [`contacts`]: contact changes from tick to tick, as events.
//! - [`outputs`]: the one place a tick's outputs are made, in the order every
//!   stream and file carries them: its events, then its [`Frame`].

pub mod contacts;
pub mod description;
pub mod outputs;
pub mod state;

use laparo_proto::v1;

pub use contacts::ContactWatch;
pub use outputs::{Holder, TickOutputs};

/// The state of the liver and the instruments after one tick.
#[derive(Debug, Default)]
pub struct Frame {
    pub tick: u64,
    pub sim_time: f64,
    /// Surface positions, packed f32 triples in the rest surface's order.
    pub surface: Vec<f32>,
    /// Every instrument's state, in scene order.
    pub instruments: Vec<v1::InstrumentState>,
}

#[cfg(test)]
mod tests;

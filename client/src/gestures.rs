//! Scripted instrument gestures: the device trajectories that simulated stations,
//! the demo, the workspace's tests and its benchmarks drive instruments with.
//!
//! A gesture is a [`Trajectory`]: simulated time `t`, s, to the instrument's tip, m,
//! and its unit axis (tip toward handle). The axes of [`press()`] and [`Probe`] pass
//! through the instrument's trocar, as a laparoscopic instrument pivots about it.
//!
//! - [`surface`]: where on the liver to aim: the rest-surface vertex nearest a
//!   trocar, the front point of the liver, an instrument's trocar.
//! - [`press`](mod@press): a repeated press along the line from the trocar, the default gesture
//!   of `laparo station` and `laparo load`.
//! - [`tip_and_shaft`](mod@tip_and_shaft): the demo's gesture, the tip pressed in and then the shaft
//!   laid across the front face and pushed in.
//! - [`probe`]: press, hold, slide while pressed, hold, withdraw: the probe of the
//!   force-error table and the coupled tests.

pub mod press;
pub mod probe;
pub mod surface;
pub mod tip_and_shaft;

#[cfg(test)]
mod tests;

pub use crate::haptics::Trajectory;
pub use press::{
    DEFAULT_DEPTH_M, DEFAULT_PERIOD_S, DEFAULT_STANDOFF_M, default_press, default_press_for, press,
};
pub use probe::{PROBE_PHASES, PROBE_SECONDS, Probe};
pub use surface::{front, front_middle, nearest_surface_vertex, trocar};
pub use tip_and_shaft::tip_and_shaft;

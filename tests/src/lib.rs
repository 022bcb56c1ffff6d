//! Shared by the workspace's integration tests (`tests/tests/`) and benchmarks
//! (`tests/benches/`): what couples the server's engine to the client's force loop.
//!
//! [`coupled::Coupled`] runs a simulation and a force loop together in simulated time,
//! as a station would over the network but with no network: the mechanics reads the
//! device's newest pose at its rate, and its local model reaches the force loop at the
//! next haptic tick.

pub mod coupled;
pub mod server;

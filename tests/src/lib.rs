//! Shared by the workspace's integration tests (`tests/tests/`) and benchmarks
//! (`tests/benches/`): what couples the server's engine to the client's force loop.
//!
//! [`coupled::Coupled`] runs a simulation and a force loop together in simulated time,
//! as a station would over the network but with no network: the mechanics reads the
//! device's newest pose at its rate, and its local model reaches the force loop at the
//! next haptic tick.
//!
//! [`server`] starts a real server on a loopback port and speaks to it;
//! [`pressing`] is a station pressing the default liver; [`recordings`] records a
//! session through a server and says what a replay of its file should send.

pub mod coupled;
pub mod pressing;
pub mod recordings;
pub mod server;

//! laparo client library: the trainee station, the 1 kHz force loop (haptics), the
//! instructor's observer and the load test.
//!
//! The client speaks the contract in [`laparo_proto`]:
//!
//! - [`connect`]: a channel to the server (http or https with a CA certificate) and
//!   the bearer-token interceptor.
//! - [`station`]: [`run_station`](station::run_station) joins a session and drives
//!   instruments through force loops on their own threads, measuring pose-to-state
//!   latency ([`latency`]) with scripted gestures ([`gestures`]).
//! - [`observe`]: [`run_observe`](observe::run_observe), a live view of a session.
//! - [`load`]: [`run_load`](load::run_load), N concurrent stations on one session.
//! - [`plot`]: `laparo replay --plot`, a recording's forces over time as a PNG.
//! - [`gestures`]: the scripted instrument gestures of simulated stations, the demo,
//!   the workspace's tests and its benchmarks.
//! - [`cmd`]: the `laparo` command line, one module per subcommand (its arguments,
//!   runner and printing).
//!
//! # Force loop
//!
//! [`haptics`] renders the instrument's reaction force at haptic rate (1 kHz by
//! default, 300–4000 Hz) from the local models the server sends at mechanics rate.
//! The network side writes each [`LocalModel`](proto::force::LocalModel) into a
//! [`ModelInbox`](haptics::ModelInbox) and reads the newest device pose from a
//! [`PoseOutbox`](haptics::PoseOutbox); the loop evaluates the newest model at every
//! device pose, blending each new model in over a transition time (1/60 s by default)
//! so the force never jumps, clamps to the device's limit and renders. Run it on its
//! own thread with [`ForceLoop::spawn`](haptics::ForceLoop::spawn), or drive
//! [`ForceLoop::tick`](haptics::ForceLoop::tick) in simulated time.

pub use laparo_proto as proto;

pub mod cmd;
pub mod connect;
pub mod gestures;
pub mod haptics;
pub mod latency;
pub mod load;
pub mod observe;
pub mod plot;
pub mod station;

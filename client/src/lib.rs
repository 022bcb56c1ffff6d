//! laparo client library: the trainee station, the 1 kHz force loop (haptics), the
//! instructor's observer, replay and the demo.
//!
//! The client speaks the contract in [`laparo_proto`]; the station, observer, replay
//! and demo land with the server and recording work.

pub use laparo_proto as proto;

pub mod haptics;

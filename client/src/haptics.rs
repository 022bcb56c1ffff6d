//! The force loop: forces rendered at haptic rate (about 1 kHz) from the local models
//! the server sends at mechanics rate (30–120 Hz).
//!
//! - [`slot`]: wait-free latest-value slots between the network side and the loop
//!   thread (models in, device poses out).
//! - [`blend`]: progressive transitions between successive local models.
//! - [`device`]: the [`HapticDevice`] trait and two simulated devices, a scripted one
//!   and a hand on a spring-damper.
//! - [`force_loop`]: [`ForceLoop::tick`], one synchronous tick, and
//!   [`ForceLoop::spawn`], the loop on its own thread against absolute deadlines.
//! - [`passivity`]: the energy the models give the hand, kept within what it put in.
//! - [`stats`]: rate, jitter, force steps, model age, clamps, missed deadlines.
//!
//! One tick: read the device pose and publish it; take the newest model if one
//! arrived; evaluate the blended models at the pose ([`crate::proto::force`] does the
//! force of one model); damp what the models would give beyond what the hand put in;
//! clamp to the device's limit keeping the direction; split into
//! axial force and torque about the trocar; render. Nothing in a tick allocates, locks
//! or blocks.

pub mod blend;
pub mod device;
pub mod force_loop;
pub mod passivity;
pub mod slot;
pub mod stats;

pub use blend::Blender;
pub use device::{
    DevicePose, HandDevice, HandParams, HapticDevice, RenderedForce, ScriptedDevice, Trajectory,
};
pub use force_loop::{ConfigError, ForceLoop, ForceLoopConfig, ForceLoopHandle, clamp_force};
pub use slot::{ModelInbox, PoseOutbox};
pub use stats::{Jitter, Limit, LoopStats};

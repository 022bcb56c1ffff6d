//! The station's instruments: for each one granted, a simulated device following its
//! gesture through a force loop on its own thread, fed the local models of the
//! instrument's states and read for its newest pose.

use std::time::Instant;

use tokio::sync::mpsc;

use super::poses::{Poses, Sent};
use super::{DEVICE_MAX_FORCE_N, GestureFn, InstrumentSummary, StationError, force_magnitude};
use crate::gestures::{default_press_for, trocar};
use crate::haptics::{
    ForceLoop, ForceLoopConfig, ForceLoopHandle, LoopStats, ModelInbox, PoseOutbox, ScriptedDevice,
};
use crate::proto::force::{LocalModel, wire};
use crate::proto::v1::{InstrumentState, SceneDescription, StationMessage};

/// One granted instrument: its force loop and what the network side knows of it.
pub(super) struct Instrument {
    pub name: String,
    inbox: ModelInbox,
    /// Offset of the force loop's haptic clock on the station clock, s.
    clock_offset_s: f64,
    outbox: PoseOutbox,
    handle: Option<ForceLoopHandle<ScriptedDevice>>,
    models: ModelIntake,
    pub force_n: f64,
    max_force_n: f64,
}

impl Instrument {
    /// Starts the force loops of the `granted` instruments of `scene`, at
    /// `haptic_rate_hz`, each device on `gesture` (by default
    /// [`default_press_for`]); `t0` is the station clock's origin. An instrument
    /// granted but missing from the scene is a protocol error.
    pub fn start_all(
        granted: &[String],
        scene: &SceneDescription,
        gesture: Option<&GestureFn>,
        haptic_rate_hz: f64,
        t0: Instant,
    ) -> Result<Vec<Instrument>, StationError> {
        let mut instruments = Vec::new();
        for name in granted {
            let Some(description) = scene.instruments.iter().find(|d| &d.name == name) else {
                return Err(StationError::Protocol(format!(
                    "instrument {name:?} was granted but is not in the scene"
                )));
            };
            let path = match gesture {
                Some(gesture) => gesture(scene, description),
                None => default_press_for(scene, description),
            };
            let device = ScriptedDevice::new(path, DEVICE_MAX_FORCE_N, 16);
            let loop_config = ForceLoopConfig {
                rate_hz: haptic_rate_hz,
                ..ForceLoopConfig::new(trocar(description))
            };
            let (force_loop, inbox, outbox) = ForceLoop::new(loop_config, device)?;
            let clock_offset_s = t0.elapsed().as_secs_f64();
            instruments.push(Instrument {
                name: name.clone(),
                inbox,
                clock_offset_s,
                outbox,
                handle: Some(force_loop.spawn()),
                models: ModelIntake::default(),
                force_n: 0.0,
                max_force_n: 0.0,
            });
        }
        Ok(instruments)
    }

    /// A state of this instrument: its local model to the force loop, its force
    /// noted.
    pub fn take(&mut self, state: &InstrumentState) {
        self.models.take(state, &mut self.inbox);
        self.force_n = force_magnitude(state);
        self.max_force_n = self.max_force_n.max(self.force_n);
    }

    /// Sends the device's newest pose, if the loop has published one, stamped with
    /// the loop's time on the station clock.
    pub fn send_pose(
        &mut self,
        poses: &mut Poses,
        outgoing: &mpsc::Sender<StationMessage>,
    ) -> Option<Sent> {
        let pose = self.outbox.latest()?;
        let device_time_s = self.clock_offset_s + pose.time;
        Some(poses.send(outgoing, &self.name, &pose.tip, &pose.axis, device_time_s))
    }

    /// The force loop's achieved rate so far, Hz.
    pub fn haptic_rate_hz(&mut self) -> f64 {
        self.handle.as_mut().map_or(0.0, |h| h.stats().rate_hz)
    }

    /// Models skipped so far.
    pub fn models_invalid(&self) -> u64 {
        self.models.invalid
    }

    /// Stops the force loop and sums the instrument up.
    pub fn stop(mut self) -> InstrumentSummary {
        let loop_stats = self
            .handle
            .take()
            .map_or_else(LoopStats::default, |h| h.stop().1);
        InstrumentSummary {
            name: self.name,
            models_applied: self.models.applied,
            models_invalid: self.models.invalid,
            max_force_n: self.max_force_n,
            loop_stats,
        }
    }
}

/// Turns the local models of an instrument's states into [`LocalModel`]s for its
/// force loop, counting those that cannot be used.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct ModelIntake {
    /// Models written to the inbox.
    pub applied: u64,
    /// Models missing or invalid, skipped.
    pub invalid: u64,
}

impl ModelIntake {
    /// Writes the state's local model to `inbox` if it is valid, counts it otherwise.
    /// Returns the model written.
    pub fn take(&mut self, state: &InstrumentState, inbox: &mut ModelInbox) -> Option<LocalModel> {
        let converted = state
            .local_model
            .as_ref()
            .ok_or(wire::WireError::Missing("local_model"))
            .and_then(LocalModel::try_from);
        match converted {
            Ok(model) => {
                inbox.write(model);
                self.applied += 1;
                Some(model)
            }
            Err(e) => {
                self.invalid += 1;
                tracing::debug!(
                    instrument = %state.instrument,
                    tick = state.tick,
                    "local model skipped: {e}"
                );
                None
            }
        }
    }
}

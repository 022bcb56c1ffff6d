//! Latest-value slots between the network side and the force-loop thread.
//!
//! A slot is a single-producer single-consumer triple buffer (the
//! [`triple_buffer`](mod@triple_buffer) crate): the writer never waits for the reader
//! nor the reader for the writer, both sides are wait-free, and neither allocates
//! after [`slot`] has built the three buffers.
//! The reader always sees the newest complete value; values written faster than they
//! are read are skipped, which is what a force loop wants (the newest local model, the
//! newest device pose), never a queue.
//!
//! The force loop uses two: models in (network → loop, [`ModelInbox`]) and device
//! poses out (loop → network, [`PoseOutbox`]).

use triple_buffer::{Input, Output, triple_buffer};

use super::DevicePose;
use crate::proto::force::LocalModel;

/// The writing end of a slot.
pub struct SlotWriter<T: Copy + Send> {
    input: Input<Option<T>>,
}

/// The reading end of a slot.
pub struct SlotReader<T: Copy + Send> {
    output: Output<Option<T>>,
}

/// A new slot, empty until its first write.
pub fn slot<T: Copy + Send>() -> (SlotWriter<T>, SlotReader<T>) {
    let (input, output) = triple_buffer(&None);
    (SlotWriter { input }, SlotReader { output })
}

impl<T: Copy + Send> SlotWriter<T> {
    /// Publishes `value` as the newest one. Wait-free, no allocation.
    pub fn write(&mut self, value: T) {
        self.input.write(Some(value));
    }

    /// Whether the reader has taken the last value written (true before any write).
    pub fn consumed(&self) -> bool {
        self.input.consumed()
    }
}

impl<T: Copy + Send> SlotReader<T> {
    /// The newest value if one was written since the last `take_new` or `latest`,
    /// `None` otherwise. Wait-free, no allocation.
    pub fn take_new(&mut self) -> Option<T> {
        if self.output.updated() {
            *self.output.read()
        } else {
            None
        }
    }

    /// The newest value written so far, new or not; `None` before the first write.
    pub fn latest(&mut self) -> Option<T> {
        *self.output.read()
    }

    /// Whether a value was written since the reader last looked.
    pub fn updated(&self) -> bool {
        self.output.updated()
    }
}

impl<T: Copy + Send> std::fmt::Debug for SlotWriter<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SlotWriter").finish_non_exhaustive()
    }
}

impl<T: Copy + Send> std::fmt::Debug for SlotReader<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SlotReader").finish_non_exhaustive()
    }
}

/// The network side's end for local models: write each model as it arrives from the
/// server; the force loop takes the newest at its next tick.
pub type ModelInbox = SlotWriter<LocalModel>;

/// The force loop's end for local models.
pub type ModelSlot = SlotReader<LocalModel>;

/// The network side's end for device poses: read the newest pose the force loop
/// sampled, to stream it to the server.
pub type PoseOutbox = SlotReader<DevicePose>;

/// The force loop's end for device poses.
pub type PoseSlot = SlotWriter<DevicePose>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reader_sees_only_the_newest_value_and_knows_when_it_is_new() {
        let (mut w, mut r) = slot::<u32>();
        assert_eq!(r.take_new(), None);
        assert_eq!(r.latest(), None);
        w.write(1);
        w.write(2);
        assert!(r.updated());
        assert_eq!(r.take_new(), Some(2));
        assert_eq!(r.take_new(), None);
        assert_eq!(r.latest(), Some(2));
        assert!(w.consumed());
    }
}

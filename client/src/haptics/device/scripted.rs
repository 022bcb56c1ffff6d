//! A device that follows a scripted path and records what it is asked to render.

use nalgebra::{Point3, Unit, Vector3};

use super::{HapticDevice, Trajectory};
use crate::proto::force::DeviceForce;

/// One force rendered by a [`ScriptedDevice`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderedForce {
    /// Haptic time of the `render` call, s.
    pub time: f64,
    /// What was rendered.
    pub force: DeviceForce,
}

/// A device whose pose follows a [`Trajectory`] and which records the rendered forces.
///
/// The record is a ring of `capacity` samples allocated up front: it keeps the last
/// `capacity` forces rendered (older ones are overwritten), so recording never
/// allocates in the force loop. [`rendered`](Self::rendered) counts every call.
pub struct ScriptedDevice {
    path: Trajectory,
    max_force: f64,
    ring: Vec<RenderedForce>,
    capacity: usize,
    head: usize,
    rendered: u64,
}

impl ScriptedDevice {
    /// A device following `path`, rendering at most `max_force` N, and keeping the
    /// last `capacity` rendered forces (at least one).
    pub fn new(path: Trajectory, max_force: f64, capacity: usize) -> Self {
        let capacity = capacity.max(1);
        ScriptedDevice {
            path,
            max_force,
            ring: Vec::with_capacity(capacity),
            capacity,
            head: 0,
            rendered: 0,
        }
    }

    /// A device holding the pose `(tip, axis)` still.
    pub fn fixed(
        tip: Point3<f64>,
        axis: Unit<Vector3<f64>>,
        max_force: f64,
        capacity: usize,
    ) -> Self {
        Self::new(Box::new(move |_| (tip, axis)), max_force, capacity)
    }

    /// How many forces were rendered in all.
    pub fn rendered(&self) -> u64 {
        self.rendered
    }

    /// How many forces the record keeps.
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    /// The last force rendered.
    pub fn last(&self) -> Option<&RenderedForce> {
        if self.ring.is_empty() {
            None
        } else {
            Some(&self.ring[(self.head + self.ring.len() - 1) % self.ring.len()])
        }
    }

    /// The recorded forces, oldest first (the last `capacity` ones).
    pub fn recorded(&self) -> impl Iterator<Item = &RenderedForce> {
        let (newer, older) = self.ring.split_at(self.head);
        older.iter().chain(newer)
    }
}

impl HapticDevice for ScriptedDevice {
    fn pose(&mut self, t: f64) -> (Point3<f64>, Unit<Vector3<f64>>) {
        (self.path)(t)
    }

    fn render(&mut self, t: f64, force: &DeviceForce) {
        let sample = RenderedForce {
            time: t,
            force: *force,
        };
        if self.ring.len() < self.capacity {
            self.ring.push(sample);
            self.head = self.ring.len() % self.capacity;
        } else {
            self.ring[self.head] = sample;
            self.head = (self.head + 1) % self.capacity;
        }
        self.rendered += 1;
    }

    fn max_force(&self) -> f64 {
        self.max_force
    }
}

impl std::fmt::Debug for ScriptedDevice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ScriptedDevice")
            .field("max_force", &self.max_force)
            .field("capacity", &self.capacity)
            .field("rendered", &self.rendered)
            .finish_non_exhaustive()
    }
}

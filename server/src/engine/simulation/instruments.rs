//! A scene's instruments, from their declarations.

use nalgebra::Point3;

use crate::engine::contact::Instrument;
use crate::engine::scene::InstrumentSpec;

/// The instrument `spec` declares, out of the body, for a mesh of `vertices` vertices.
pub(super) fn instrument(spec: &InstrumentSpec, vertices: usize) -> Instrument {
    Instrument {
        tip_contact: spec.tip_contact,
        shaft_contact: spec.shaft_contact,
        friction: spec.friction,
        ..Instrument::new(
            spec.name.clone(),
            spec.radius,
            spec.length,
            Point3::from(spec.trocar),
            vertices,
        )
    }
}

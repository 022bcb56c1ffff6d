//! An instrument as the contact stage tracks it, and what each tick reports of it.

use nalgebra::{Point3, Unit, Vector3};

use super::pose::InstrumentPose;

/// One laparoscopic instrument: its geometry, its poses at the start and end of the
/// tick, and the vertices it holds.
#[derive(Clone, Debug)]
pub struct Instrument {
    pub name: String,
    /// Shaft radius r, m.
    pub radius: f64,
    /// Shaft length l inside the body, m.
    pub length: f64,
    /// Trocar point, m; torques are taken about it.
    pub trocar: Point3<f64>,
    /// Whether the tip pushes tissue (the tip triangle onto the plane at distance r).
    pub tip_contact: bool,
    /// Whether the shaft pushes tissue. Without it the instrument is its tip alone,
    /// a ball of radius r at `P`, as in a point-contact simulator.
    pub shaft_contact: bool,
    /// Coulomb friction coefficient μ of the hold (see the contact stage).
    pub friction: f64,
    /// The pose at the end of the previous tick; `None` while out of the body.
    pub previous: Option<InstrumentPose>,
    /// The pose for this tick; `None` takes the instrument out of the body.
    pub current: Option<InstrumentPose>,
    /// Vertices this instrument holds (imposed on the elastic model).
    pub held: Vec<u32>,
    /// What the last tick found.
    pub report: ContactReport,
}

/// What the contact stage found for one instrument in one tick: what the force model
/// needs (paper §3).
#[derive(Clone, Debug, Default)]
pub struct ContactReport {
    /// Edges that crossed the axis during the tick (§2.3).
    pub colliding_edges: u32,
    /// Vertices the stage moved this tick.
    pub moved_vertices: u32,
    /// The tip contact, if the axis met the surface within the shaft (§2.5).
    pub tip: Option<TipContact>,
    /// The surface point closest to the tip within the approach reach, with its
    /// normal (eq. 7), when the axis does not meet the surface: where a tip contact
    /// would begin (see [`super::stage::APPROACH_SPEED`]).
    pub nearest: Option<NearestSurface>,
    /// Surface edges with a held vertex that lie along the shaft: the "neighbouring
    /// edges" of the shaft plane (§3).
    pub shaft_edges: Vec<u32>,
    /// The tissue's force on the instrument, N: the sum of [`Self::held_reactions`].
    pub reaction: Vector3<f64>,
    /// The tissue's force on the instrument at each held vertex, N, in the order of
    /// [`Instrument::held`]: its elastic reaction `−(K u)_i`, scaled on the tip's end
    /// to the tip's own footprint when the scene asks (`contact.footprint`, see
    /// `footprint`).
    pub held_reactions: Vec<Vector3<f64>>,
}

/// The surface point nearest the tip.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NearestSurface {
    /// The point, m.
    pub point: Point3<f64>,
    /// The surface normal there (eq. 7), out of the tissue.
    pub normal: Unit<Vector3<f64>>,
    /// The surface triangle that holds it.
    pub triangle: u32,
}

/// The tip contact of §2.5.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TipContact {
    /// `P_prox`: where the axis met the surface, m.
    pub p_prox: Point3<f64>,
    /// `n_prox` (eq. 7): the surface normal there, pointing out of the tissue.
    pub n_prox: Unit<Vector3<f64>>,
    /// The surface triangle that held `P_prox`.
    pub triangle: u32,
}

impl Instrument {
    /// An instrument named `name`, of shaft radius `radius` and length `length` (m),
    /// entering through `trocar`, out of the body, for a mesh of `vertices` vertices.
    /// It pushes tissue with its tip and its shaft, without friction; set
    /// `tip_contact`, `shaft_contact` and `friction` for another kind.
    pub fn new(
        name: impl Into<String>,
        radius: f64,
        length: f64,
        trocar: Point3<f64>,
        vertices: usize,
    ) -> Self {
        Instrument {
            name: name.into(),
            radius,
            length,
            trocar,
            tip_contact: true,
            shaft_contact: true,
            friction: 0.0,
            previous: None,
            current: None,
            held: Vec::with_capacity(vertices),
            report: ContactReport {
                shaft_edges: Vec::with_capacity(vertices),
                held_reactions: Vec::with_capacity(vertices),
                ..ContactReport::default()
            },
        }
    }

    /// The length of axis that pushes tissue: `l`, or 0 (the tip ball) without shaft
    /// contact.
    pub fn active_length(&self) -> f64 {
        if self.shaft_contact { self.length } else { 0.0 }
    }
}

impl ContactReport {
    pub(super) fn clear(&mut self) {
        self.colliding_edges = 0;
        self.moved_vertices = 0;
        self.tip = None;
        self.nearest = None;
        self.shaft_edges.clear();
        self.held_reactions.clear();
        self.reaction = Vector3::zeros();
    }
}

//! The contact stage (paper §2): keeping the liver's surface out of the instruments.
//!
//! Each tick the stage looks at the mesh from each instrument. The instrument is the set
//! of points within its radius `r` of the axis segment `{P + s·Z : 0 ≤ s ≤ l}` (`P` the
//! tip, `Z` the unit axis toward the handle, `l` the shaft length). The previous vertex
//! positions are carried along with the instrument's rigid motion, so that in the
//! instrument's frame only the mesh moves, each vertex on a straight line over the step
//! (§2.2). Then (§2.3–2.6): find the *colliding edges* that crossed the axis during the
//! step; give each of their vertices a *confidence interval* of the step in which none
//! of its edges crosses, and move it to the middle of it; move the triangle under the
//! tip onto a plane at distance `r` from the tip; push the remaining edges and vertices
//! out of the cylinder.
//!
//! Files, by concern:
//!
//! - [`stage`]: the stage around the elastic step — held vertices follow their
//!   instrument, then per instrument the steps below in sub-moves of at most 2° of
//!   turn, then hold and release (`stage/holding`), the settling and what it lets go
//!   (`stage/settling`); the tick's report for the force model (`stage/reaction`).
//! - [`broadphase`]: parry's BVH over the surface triangles' motion in the instrument's
//!   frame; every triangle that may have met the instrument, at any speed.
//! - `edges`: colliding edges and confidence intervals (§2.3–2.4).
//! - `tip`: the triangle under the tip onto the plane at distance `r` (§2.5).
//! - `push`: edges and vertices out of the instrument (§2.6), with
//! - `faces`: triangle interiors out of it, the correction shared by the triangle's
//!   vertices (least-norm barycentric mapping).
//! - `footprint`: on the scene's request (`contact.footprint`), the tip's force
//!   scaled from the patch of vertices the mesh holds to the tip's own footprint,
//!   so that a press feels the same on a coarse mesh as on a fine one.
//! - [`instrument`]: an instrument's geometry, poses, held vertices and report.
//! - `settle`: the free tissue around what the contact steps jumped, corrected
//!   statically with it, so that a first contact does not spike.
//! - `scratch`: the buffers the stage and its steps share, allocated once, and the
//!   stage's work counters.
//! - Pure geometry, plain data in and out, no allocation:
//!   [`pose`] (the rigid motion of eq. 1), [`crossing`] (eq. 2–6 derived again, the
//!   printed typos corrected and every degenerate case decided), [`closest`] (closest
//!   points for the push-out, ray–triangle and eq. 7's `n_prox`).
//!
//! Supports (fixed vertices) never move: an edge or a vertex that is all support is
//! not kept out of an instrument, and a scene should keep its instruments away from
//! its supports. An instrument that first appears already inside the tissue (no
//! previous pose, so no motion to analyse) is cleared by the tip press and the
//! push-out with its face pass: the tissue goes to the side of its surface away from
//! the handle (see `faces`). Instruments are expected to enter from outside, as
//! through a trocar: a shaft that passes through a second lobe as well is not cleared
//! of it.

pub mod broadphase;
pub mod closest;
pub mod crossing;
mod edges;
mod faces;
mod footprint;
mod hold;
pub mod instrument;
pub mod pose;
mod push;
mod scratch;
mod settle;
pub mod stage;
mod tip;

pub use crossing::{Crossing, CrossingKind, EdgeEnd, MovingEdge, closer_to_axis, edge_crossing};
pub use hold::contact_normal;
pub use instrument::{ContactReport, Instrument, NearestSurface, TipContact};
pub use pose::{InstrumentPose, rigid_motion};
pub use scratch::ContactStats;
pub use stage::{ContactStage, MAX_INSTRUMENTS};

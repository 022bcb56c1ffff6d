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
//! This module holds the pure geometry of those steps — plain data in, plain data out,
//! no allocation, so every function can run every tick:
//!
//! - [`pose`]: the instrument's pose and the rigid motion between two poses (eq. 1).
//! - [`crossing`]: whether a moving edge crossed the axis segment, when and where
//!   (eq. 2–5, derived again with the printed typos corrected and every degenerate case
//!   decided), and whether a vertex's motion drives its edge toward the axis (eq. 6,
//!   corrected).
//! - [`closest`]: closest points between an edge and the axis segment and from a point
//!   to it (pushing out, §2.6), ray–triangle intersection with barycentric coordinates
//!   and the closest point of a triangle (locating `P_prox`, §2.5), and the interpolated
//!   normal `n_prox` (eq. 7).

pub mod broadphase;
pub mod closest;
pub mod crossing;
mod edges;
pub mod instrument;
pub mod pose;
mod push;
pub mod stage;
mod tip;

pub use crossing::{Crossing, CrossingKind, EdgeEnd, MovingEdge, closer_to_axis, edge_crossing};
pub use instrument::{ContactReport, Instrument, TipContact};
pub use pose::{InstrumentPose, rigid_motion};
pub use stage::{ContactStage, ContactStats};

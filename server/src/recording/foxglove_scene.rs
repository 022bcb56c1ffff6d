//! The recording as Foxglove draws it: one `foxglove.SceneUpdate` per written tick,
//! with Foxglove's well-known schema, so that a recording opens in Foxglove as a 3D
//! scene without any schema of ours.
//!
//! Entities, all in the frame [`FRAME_ID`] (the scene's world frame, m):
//!
//! - `liver`: the deformed surface as an indexed triangle list: the tick's surface
//!   positions as points, the rest surface's triangles as indices into them (a
//!   third of the bytes of three points per triangle, and the indices, the same
//!   at every tick, all but vanish in a compressed chunk);
//! - one per instrument, named as the instrument: its shaft as a cylinder, the
//!   segment from the tip `P` to `P + l·Z` of radius `r` (`Z` the axis, from the
//!   tip toward the handle); no primitive while the instrument has no pose;
//! - `<instrument>/force`: the reaction force on the instrument as an arrow from the
//!   point of the axis where it applies, along the force, [`ARROW_M_PER_N`] long per
//!   newton; no primitive while the force is zero.
//!
//! Every entity is sent at every update and replaces the previous one of its id.
//!
//! Updates are written for one tick in [`stride`], at most [`MAX_RATE_HZ`] a
//! second: the 3D view is for looking at, and every tick of it would make this
//! channel most of the file (Foxglove's points are f64 triples: on liver-20k at
//! 60 Hz it was 81% of the bytes, 143 MB per simulated minute in all). The
//! contract's `/surface` channel keeps every tick for replay and re-simulation.

use foxglove::schemas::{
    ArrowPrimitive, Color, CylinderPrimitive, Point3, Pose, Quaternion, SceneEntity, SceneUpdate,
    Timestamp, TriangleListPrimitive, Vector3,
};
use laparo_proto::force::LocalModel;
use laparo_proto::force::wire::pose;
use laparo_proto::v1;
use nalgebra::{Unit, UnitQuaternion};

use crate::frame::Frame;

/// Frame of every entity: the scene's world frame.
pub const FRAME_ID: &str = "world";
/// Id of the liver's entity.
pub const LIVER_ID: &str = "liver";
/// Length of a force arrow per newton of force: 10 mm per N, so that the forces of
/// a session (up to a few N) are drawn at the size of the liver's features.
pub const ARROW_M_PER_N: f64 = 0.01;
/// Share of an arrow's length taken by its head.
pub const ARROW_HEAD_SHARE: f64 = 0.2;
/// Diameters of an arrow's shaft and head, m.
pub const ARROW_SHAFT_DIAMETER_M: f64 = 0.002;
pub const ARROW_HEAD_DIAMETER_M: f64 = 0.004;

const LIVER_COLOR: Color = Color {
    r: 0.70,
    g: 0.26,
    b: 0.22,
    a: 1.0,
};
const INSTRUMENT_COLOR: Color = Color {
    r: 0.72,
    g: 0.74,
    b: 0.78,
    a: 1.0,
};
const FORCE_COLOR: Color = Color {
    r: 1.0,
    g: 0.84,
    b: 0.0,
    a: 1.0,
};

/// Id of the entity drawing instrument `name`'s force.
pub fn force_id(name: &str) -> String {
    format!("{name}/force")
}

/// An instrument as drawn.
#[derive(Clone, Debug)]
struct Shaft {
    name: String,
    radius: f64,
    length: f64,
}

/// Most Foxglove scene updates a simulated second, Hz.
pub const MAX_RATE_HZ: f64 = 20.0;

/// One tick in how many is drawn at mechanics rate `rate_hz`: the smallest
/// stride that keeps the updates at or under [`MAX_RATE_HZ`].
pub fn stride(rate_hz: f64) -> u64 {
    if rate_hz.is_finite() && rate_hz > MAX_RATE_HZ {
        (rate_hz / MAX_RATE_HZ).ceil() as u64
    } else {
        1
    }
}

/// Whether tick `tick` (from 1) is drawn with `stride`: the first tick, then every
/// `stride`-th.
pub fn drawn(tick: u64, stride: u64) -> bool {
    tick.saturating_sub(1).is_multiple_of(stride.max(1))
}

/// Builds a session's scene updates from its description and its frames.
#[derive(Clone, Debug)]
pub struct SceneUpdates {
    /// The rest surface's triangles, three indices each into the surface vertices.
    triangles: Vec<u32>,
    instruments: Vec<Shaft>,
}

impl SceneUpdates {
    pub fn new(description: &v1::SceneDescription) -> Self {
        SceneUpdates {
            triangles: description
                .rest_surface
                .as_ref()
                .map(|s| s.triangles.clone())
                .unwrap_or_default(),
            instruments: description
                .instruments
                .iter()
                .map(|i| Shaft {
                    name: i.name.clone(),
                    radius: i.radius_m,
                    length: i.length_m,
                })
                .collect(),
        }
    }

    /// The update of `frame`, stamped `log_time` (ns since the Unix epoch).
    pub fn update(&self, frame: &Frame, log_time: u64) -> SceneUpdate {
        let timestamp = Some(Timestamp::new(
            (log_time / 1_000_000_000).min(u32::MAX as u64) as u32,
            (log_time % 1_000_000_000) as u32,
        ));
        let entity = |id: String| SceneEntity {
            timestamp,
            frame_id: FRAME_ID.into(),
            id,
            ..SceneEntity::default()
        };
        let mut entities = Vec::with_capacity(1 + 2 * self.instruments.len());
        entities.push(SceneEntity {
            triangles: vec![self.liver(&frame.surface)],
            ..entity(LIVER_ID.into())
        });
        for shaft in &self.instruments {
            let state = frame
                .instruments
                .iter()
                .find(|s| s.instrument == shaft.name);
            let state_pose = state.and_then(|s| pose(s.pose.as_ref()).ok());
            entities.push(SceneEntity {
                cylinders: state_pose
                    .map(|(tip, axis)| shaft.cylinder(&tip, &axis))
                    .into_iter()
                    .collect(),
                ..entity(shaft.name.clone())
            });
            entities.push(SceneEntity {
                arrows: state.and_then(force_arrow).into_iter().collect(),
                ..entity(force_id(&shaft.name))
            });
        }
        SceneUpdate {
            deletions: Vec::new(),
            entities,
        }
    }

    /// The liver's triangle list: the surface vertices as points, the triangles as
    /// indices into them.
    fn liver(&self, positions: &[f32]) -> TriangleListPrimitive {
        TriangleListPrimitive {
            pose: Some(identity()),
            points: positions
                .chunks_exact(3)
                .map(|p| Point3 {
                    x: p[0].into(),
                    y: p[1].into(),
                    z: p[2].into(),
                })
                .collect(),
            color: Some(LIVER_COLOR),
            colors: Vec::new(),
            indices: self.triangles.clone(),
        }
    }
}

impl Shaft {
    /// The cylinder of the shaft at tip `tip` and axis `axis`: Foxglove's cylinder
    /// is centred on its pose with its flat faces across the pose's z, so the pose
    /// is the middle of the shaft, `P + (l/2)·Z`, with z turned onto `Z`.
    fn cylinder(
        &self,
        tip: &nalgebra::Point3<f64>,
        axis: &Unit<nalgebra::Vector3<f64>>,
    ) -> CylinderPrimitive {
        let centre = tip + axis.into_inner() * (self.length / 2.0);
        let diameter = 2.0 * self.radius;
        CylinderPrimitive {
            pose: Some(Pose {
                position: Some(vector(&centre.coords)),
                orientation: Some(quaternion(&turning(&nalgebra::Vector3::z_axis(), axis))),
            }),
            size: Some(Vector3 {
                x: diameter,
                y: diameter,
                z: self.length,
            }),
            bottom_scale: 1.0,
            top_scale: 1.0,
            color: Some(INSTRUMENT_COLOR),
        }
    }
}

/// The arrow of an instrument's recorded force: from the point of the axis where the
/// force applies (the local model's, see [`LocalModel::force`]; the tip when the
/// model cannot be read), along the force (Foxglove's arrow points along its
/// pose's x), [`ARROW_M_PER_N`] long per newton. `None` without force.
fn force_arrow(state: &v1::InstrumentState) -> Option<ArrowPrimitive> {
    let f = state.force.as_ref()?.force.as_ref()?;
    let force = nalgebra::Vector3::new(f.x, f.y, f.z);
    let magnitude = force.norm();
    if !(magnitude > 0.0 && magnitude.is_finite()) {
        return None;
    }
    let point = state
        .local_model
        .as_ref()
        .and_then(|m| LocalModel::try_from(m).ok())
        .map(|m| m.force(&m.tip, &m.axis).point)
        .or_else(|| pose(state.pose.as_ref()).ok().map(|(tip, _)| tip))?;
    let length = ARROW_M_PER_N * magnitude;
    let direction = Unit::new_unchecked(force / magnitude);
    Some(ArrowPrimitive {
        pose: Some(Pose {
            position: Some(vector(&point.coords)),
            orientation: Some(quaternion(&turning(
                &nalgebra::Vector3::x_axis(),
                &direction,
            ))),
        }),
        shaft_length: length * (1.0 - ARROW_HEAD_SHARE),
        shaft_diameter: ARROW_SHAFT_DIAMETER_M,
        head_length: length * ARROW_HEAD_SHARE,
        head_diameter: ARROW_HEAD_DIAMETER_M,
        color: Some(FORCE_COLOR),
    })
}

/// The rotation turning `from` onto `to`; half a turn about an axis across `from`
/// when they are opposite.
fn turning(
    from: &Unit<nalgebra::Vector3<f64>>,
    to: &Unit<nalgebra::Vector3<f64>>,
) -> UnitQuaternion<f64> {
    UnitQuaternion::rotation_between_axis(from, to).unwrap_or_else(|| {
        let across = if from.x.abs() < 0.9 {
            nalgebra::Vector3::x()
        } else {
            nalgebra::Vector3::y()
        };
        let across = Unit::new_normalize(from.cross(&across));
        UnitQuaternion::from_axis_angle(&across, std::f64::consts::PI)
    })
}

fn vector(v: &nalgebra::Vector3<f64>) -> Vector3 {
    Vector3 {
        x: v.x,
        y: v.y,
        z: v.z,
    }
}

fn quaternion(q: &UnitQuaternion<f64>) -> Quaternion {
    Quaternion {
        x: q.i,
        y: q.j,
        z: q.k,
        w: q.w,
    }
}

fn identity() -> Pose {
    Pose {
        position: Some(Vector3::default()),
        orientation: Some(Quaternion {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }),
    }
}

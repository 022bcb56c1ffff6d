//! The local model and poses to and from the contract's messages, checking what
//! arrives: whatever a peer sends, a bad value is an error that names the field, never
//! a NaN inside a force loop.

use nalgebra::{Point3, Unit, Vector3};
use thiserror::Error;

use super::{ForceModel, LocalModel, Plane};
use crate::v1;

/// How far from 1 the norm of a unit vector on the wire may be. A vector normalised
/// in f64 is within 1e-15 of unit length, one normalised in f32 within about 1e-7;
/// 1e-6 accepts both and refuses any vector that was not meant to be unit.
pub const UNIT_TOLERANCE: f64 = 1e-6;

/// A message field that cannot be used.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum WireError {
    #[error("{0} is missing")]
    Missing(&'static str),
    #[error("{0} is not finite")]
    NotFinite(&'static str),
    #[error("{field} is not a unit vector (norm {norm})")]
    NotUnit { field: &'static str, norm: f64 },
    #[error("{field} must be ≥ 0 (got {value})")]
    Negative { field: &'static str, value: f64 },
}

/// A finite vector from the wire.
pub fn vector(v: Option<&v1::Vec3>, field: &'static str) -> Result<Vector3<f64>, WireError> {
    let v = v.ok_or(WireError::Missing(field))?;
    let out = Vector3::new(v.x, v.y, v.z);
    if out.iter().all(|c| c.is_finite()) {
        Ok(out)
    } else {
        Err(WireError::NotFinite(field))
    }
}

/// A unit vector from the wire (within [`UNIT_TOLERANCE`]), renormalised.
pub fn unit(v: Option<&v1::Vec3>, field: &'static str) -> Result<Unit<Vector3<f64>>, WireError> {
    let v = vector(v, field)?;
    let norm = v.norm();
    if (norm - 1.0).abs() <= UNIT_TOLERANCE {
        Ok(Unit::new_normalize(v))
    } else {
        Err(WireError::NotUnit { field, norm })
    }
}

/// A pose `(P, Z)` from the wire.
pub fn pose(p: Option<&v1::Pose>) -> Result<(Point3<f64>, Unit<Vector3<f64>>), WireError> {
    let p = p.ok_or(WireError::Missing("pose"))?;
    let tip = vector(p.tip.as_ref(), "pose.tip")?;
    let axis = unit(p.axis.as_ref(), "pose.axis")?;
    Ok((Point3::from(tip), axis))
}

/// A vector to the wire.
pub fn to_vec3(v: &Vector3<f64>) -> v1::Vec3 {
    v1::Vec3 {
        x: v.x,
        y: v.y,
        z: v.z,
    }
}

/// A pose to the wire.
pub fn to_pose(tip: &Point3<f64>, axis: &Unit<Vector3<f64>>) -> v1::Pose {
    v1::Pose {
        tip: Some(to_vec3(&tip.coords)),
        axis: Some(to_vec3(axis)),
    }
}

fn plane(
    p: Option<&v1::LocalPlane>,
    normal: &'static str,
    anchor: &'static str,
    stiffness: &'static str,
    drag: &'static str,
) -> Result<Option<Plane>, WireError> {
    let Some(p) = p.filter(|p| p.active) else {
        return Ok(None);
    };
    let k = p.stiffness_n_per_m;
    if !k.is_finite() {
        return Err(WireError::NotFinite(stiffness));
    }
    if k < 0.0 {
        return Err(WireError::Negative {
            field: stiffness,
            value: k,
        });
    }
    let drag = match p.drag_n.as_ref() {
        Some(d) => vector(Some(d), drag)?,
        None => Vector3::zeros(),
    };
    Ok(Some(Plane {
        normal: unit(p.normal.as_ref(), normal)?,
        anchor: Point3::from(vector(p.anchor.as_ref(), anchor)?),
        stiffness: k,
        drag,
    }))
}

fn to_plane(p: &Option<Plane>) -> v1::LocalPlane {
    match p {
        Some(p) => v1::LocalPlane {
            active: true,
            normal: Some(to_vec3(&p.normal)),
            anchor: Some(to_vec3(&p.anchor.coords)),
            stiffness_n_per_m: p.stiffness,
            drag_n: (p.drag != Vector3::zeros()).then(|| to_vec3(&p.drag)),
        },
        None => v1::LocalPlane::default(),
    }
}

impl TryFrom<&v1::LocalModel> for LocalModel {
    type Error = WireError;

    fn try_from(m: &v1::LocalModel) -> Result<Self, WireError> {
        if !m.sim_time_s.is_finite() {
            return Err(WireError::NotFinite("sim_time_s"));
        }
        let (tip, axis) = pose(m.pose.as_ref())?;
        let tip_plane = plane(
            m.tip_plane.as_ref(),
            "tip_plane.normal",
            "tip_plane.anchor",
            "tip_plane.stiffness_n_per_m",
            "tip_plane.drag_n",
        )?;
        let shaft_plane = plane(
            m.shaft_plane.as_ref(),
            "shaft_plane.normal",
            "shaft_plane.anchor",
            "shaft_plane.stiffness_n_per_m",
            "shaft_plane.drag_n",
        )?;
        let young_modulus = match m.young_modulus_pa {
            Some(e) if !e.is_finite() => return Err(WireError::NotFinite("young_modulus_pa")),
            Some(e) if e < 0.0 => {
                return Err(WireError::Negative {
                    field: "young_modulus_pa",
                    value: e,
                });
            }
            e => e,
        };
        let kind = match v1::ForceModelKind::try_from(m.force_model) {
            Ok(v1::ForceModelKind::Calibrated) => ForceModel::Calibrated,
            // Unspecified or a kind newer than this build: the paper's model.
            _ => ForceModel::Geometric,
        };
        Ok(LocalModel {
            tick: m.tick,
            sim_time: m.sim_time_s,
            tip,
            axis,
            tip_plane,
            shaft_plane,
            kind,
            young_modulus,
        })
    }
}

impl From<&LocalModel> for v1::LocalModel {
    fn from(m: &LocalModel) -> Self {
        v1::LocalModel {
            tick: m.tick,
            sim_time_s: m.sim_time,
            pose: Some(to_pose(&m.tip, &m.axis)),
            tip_plane: Some(to_plane(&m.tip_plane)),
            shaft_plane: Some(to_plane(&m.shaft_plane)),
            force_model: match m.kind {
                ForceModel::Geometric => v1::ForceModelKind::Geometric,
                ForceModel::Calibrated => v1::ForceModelKind::Calibrated,
            } as i32,
            young_modulus_pa: m.young_modulus,
        }
    }
}

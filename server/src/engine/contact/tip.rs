//! The tip (paper §2.5): the triangle under the tip goes onto a plane in front of it.
//!
//! `P_prox` is where the axis segment meets the surface nearest the tip (the ray from
//! `P` toward the handle). Its normal `n_prox` (eq. 7) interpolates the vertex normals
//! of its triangle at the current positions. The triangle's vertices are projected
//! along `Z` onto the plane `𝒫` of normal `n_prox` through `P − r·n_prox`: at distance
//! `r` from the tip, on the tissue's side. Moving them along `Z` keeps their shadow on
//! the plane ⊥ `Z`, so no edge crosses the axis by it, and the axis leaves the triangle
//! behind the tip. If the axis meets the surface again further up, the next triangle
//! follows (a fold), a few times at most.
//!
//! When it acts. A press that comes in from outside at the speed of a hand is taken
//! first by the push-out (§2.6) and the faces, whose held vertices then follow the
//! instrument, so the axis point never falls short of the plane and nothing here
//! moves: the convergence bench (tip 8 and 15 mm, shaft 10 mm, ramped from 1 cm out)
//! prints the same digits when this press instead moves only the axis point onto the
//! plane by least norm, as the faces do (measured). What it moves is a first pose
//! inside the liver and a jab of more than a radius in one tick; there a coarse
//! triangle laid whole on the plane moves vertices several radii from the axis (2 cm
//! first pose, liver at 100 kPa, ν 0.49: a vertex 4.6 r off the axis jumps 2 cm and
//! inverts two elements). The least-norm move cut that case's largest force from 486
//! to 104 N but let a jab at ν 0.499 go after 0.05 s and a deep fast pivot hold the
//! liver 1 s after withdrawal, so the paper's plane stays.
//!
//! A triangle seen nearly edge-on (`n·Z` small) would be thrown far along `Z`; below
//! [`GRAZING`] the triangle's own face normal is used if it faces the instrument
//! better, and if neither does the triangle is left to the push-out of §2.6.

use nalgebra::{Point3, Unit};

use super::closest::{closest_point_triangle, interpolated_normal, ray_triangle};
use super::instrument::{NearestSurface, TipContact};
use super::pose::InstrumentPose;
use super::scratch::Scratch;
use crate::engine::mesh::Surface;

/// `n·Z` below which a plane is too oblique to project onto along `Z`: at 0.2
/// (78° from the axis) a vertex moves at most 5× its distance to the plane.
const GRAZING: f64 = 0.2;
/// Triangles met one after another along the axis (folds) handled per tick.
const MAX_LAYERS: usize = 4;

/// Presses the triangles the axis meets within `reach` of the tip onto the tip plane.
/// Returns the first contact, if any.
pub(super) fn press_tip(
    s: &mut Scratch,
    surface: &Surface,
    pose: &InstrumentPose,
    radius: f64,
    reach: f64,
    x: &mut [Point3<f64>],
) -> Option<TipContact> {
    let z = pose.axis.into_inner();
    let mut first = None;
    for _ in 0..MAX_LAYERS {
        let mut best: Option<(f64, u32, [f64; 3])> = None;
        for &t in &s.triangles {
            let tri = surface.triangles[t as usize].map(|v| x[v as usize]);
            if let Some(hit) = ray_triangle(&pose.tip, &z, &tri)
                && hit.t <= reach
                && best.is_none_or(|b| hit.t < b.0)
            {
                best = Some((hit.t, t, hit.barycentric));
            }
        }
        let (depth, t, bary) = best?;
        let tri = surface.triangles[t as usize];
        let normals = tri.map(|v| surface.vertex_normal(v, x));
        let p_prox = pose.tip + z * depth;
        let face = {
            let p = tri.map(|v| x[v as usize]);
            Unit::try_new((p[1] - p[0]).cross(&(p[2] - p[0])), 0.0)
        };
        let n = match interpolated_normal(&bary, &normals) {
            Some(n) if n.dot(&z) >= GRAZING => Some(n),
            other => face
                .filter(|f| f.dot(&z) >= GRAZING)
                .or(other.filter(|n| n.dot(&z) > 0.0)),
        };
        let Some(n) = n else {
            first = first.or(Some(TipContact {
                p_prox,
                n_prox: face.unwrap_or(pose.axis),
                triangle: t,
            }));
            break;
        };
        first = first.or(Some(TipContact {
            p_prox,
            n_prox: n,
            triangle: t,
        }));
        if n.dot(&z) < GRAZING {
            break;
        }
        let q = pose.tip - n.into_inner() * radius;
        for v in tri {
            let vi = v as usize;
            if s.fixed[vi] {
                continue;
            }
            let along = (q - x[vi]).dot(&n) / n.dot(&z);
            if along < 0.0 {
                x[vi] += z * along;
                s.touch(v);
            }
        }
    }
    first
}

/// The surface point nearest the tip among the candidate triangles, with its normal.
pub(super) fn nearest_point(
    s: &Scratch,
    surface: &Surface,
    pose: &InstrumentPose,
    x: &[Point3<f64>],
) -> Option<NearestSurface> {
    let mut best: Option<(f64, Point3<f64>, u32, [f64; 3])> = None;
    for &t in &s.triangles {
        let tri = surface.triangles[t as usize];
        let c = closest_point_triangle(&pose.tip, &tri.map(|v| x[v as usize]));
        let d = (c.point - pose.tip).norm();
        if best.is_none_or(|b| d < b.0) {
            best = Some((d, c.point, t, c.barycentric));
        }
    }
    let (_, point, t, bary) = best?;
    let normals = surface.triangles[t as usize].map(|v| surface.vertex_normal(v, x));
    interpolated_normal(&bary, &normals).map(|normal| NearestSurface {
        point,
        normal,
        triangle: t,
    })
}

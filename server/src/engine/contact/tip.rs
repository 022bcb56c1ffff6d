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
//!
//! A back face. The ray can meet a triangle whose outward normal faces away from the
//! handle (`n·Z ≤ −GRAZING`): the tip is on its outward side and the shaft behind it on
//! its tissue side. That is a thin part of the liver the tip pressed through when
//! three things hold: the face went over the tip by the tip's own advance in this
//! sub-move (the point of it the axis now meets, at `t` above the tip, was at `β₀ ≤ 0`
//! at the sub-move's start, `rel_start` in the instrument's frame, and rose by
//! `t − β₀` no more than the tip advanced along `−Z`); and a face toward the handle
//! lies ahead of the tip within `r / GRAZING` (the front face it presses, on the tip
//! plane). The back face then came over the tip face on, through the front one, none
//! of its edges crossing the axis for §2.3–2.4 to stop: a 5 cm tilted jab into
//! liver-5k's lower lip in one tick left the axis through a back face 1.6 mm above the
//! tip, the surface turned inside out there. Such a face is pressed ahead with the
//! front one, onto the plane of normal `m = −n` (oriented toward the handle, as a front
//! face's) through `P − r·m`: the part of the liver between them flattened ahead of the
//! tip, as the tip pushes it. Any other back face is left, as before: a tip that has
//! gone into the tissue (no front face ahead) leaves through it, and one the tissue's
//! own motion brings over a still tip is a second lobe the shaft passes through (see
//! the module notes of `contact`). Pressed ahead in those cases, a deep pivot through
//! the liver hooked it and held it 0.22 m off its rest a second after withdrawal
//! (`tests/contact_release.rs`).

use nalgebra::{Point3, Unit, Vector3};

use super::closest::{closest_point_triangle, interpolated_normal, ray_triangle};
use super::instrument::{NearestSurface, TipContact};
use super::pose::InstrumentPose;
use super::scratch::Scratch;
use crate::engine::mesh::Surface;

/// `n·Z` below which a plane is too oblique to project onto along `Z`: at 0.2
/// (78° from the axis) a vertex moves at most 5× its distance to the plane.
const GRAZING: f64 = 0.2;
/// How far from the axis a corner of the pressed triangle may be, in lengths of its own
/// longest rest edge beyond the radius, to be laid on the tip plane.
///
/// A triangle under the tip has its corners within an edge of the axis, as long as
/// that edge is; the tissue around a press stretches its edges by tens of percent.
/// A corner further off belongs to a triangle a drag has stretched across the
/// instrument, and projecting it along `Z` moves it by its distance to the plane over
/// `n·Z`, whatever that is: a shaft through the liver beside its supports, turned
/// about its tip, dragged one corner 0.85 m out with the triangle still across the
/// axis, and the press threw that corner 2.2 m in one tick
/// (`tests/contact_hard_cases.rs`). Such a corner is left where it is, as a support
/// is; the other corners are still laid on the plane. Five rest edges is a stretch
/// no tissue takes (55 mm on the coarse liver).
pub(super) const MAX_STRETCH: f64 = 5.0;

/// Triangles met one after another along the axis (folds) handled per tick.
const MAX_LAYERS: usize = 4;

/// Which triangles the press takes.
pub(super) struct Reach {
    /// How far up the axis from the tip it takes faces toward the handle, m.
    pub front: f64,
    /// The tip's advance along `−Z` over the sub-move that started at `rel_start`, m,
    /// for back faces it pressed through (see the module notes); `None` when the
    /// press follows no motion.
    pub back: Option<f64>,
}

/// Presses the triangles the axis meets within `reach` of the tip onto the tip plane.
/// Returns the first contact, if any.
pub(super) fn press_tip(
    s: &mut Scratch,
    surface: &Surface,
    pose: &InstrumentPose,
    radius: f64,
    reach: Reach,
    x: &mut [Point3<f64>],
) -> Option<TipContact> {
    let z = pose.axis.into_inner();
    let mut first = None;
    for _ in 0..MAX_LAYERS {
        let mut best: Option<(f64, u32, [f64; 3])> = None;
        for &t in &s.triangles {
            let tri = surface.triangles[t as usize].map(|v| x[v as usize]);
            if let Some(hit) = ray_triangle(&pose.tip, &z, &tri)
                && hit.t <= reach.front
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
        let interpolated = interpolated_normal(&bary, &normals);
        let n = match interpolated {
            Some(n) if n.dot(&z) >= GRAZING => Some(n),
            other => face
                .filter(|f| f.dot(&z) >= GRAZING)
                .or(other.filter(|n| n.dot(&z) > 0.0)),
        };
        // A back face the tip went through: its plane oriented toward the handle.
        let n = n.or_else(|| {
            let advance = reach.back?;
            let back = |n: &Unit<Vector3<f64>>| -n.dot(&z) >= GRAZING;
            let n = interpolated.filter(back).or(face.filter(back))?;
            let start: Point3<f64> = tri
                .iter()
                .zip(bary)
                .map(|(&v, w)| s.rel_start[v as usize].coords * w)
                .sum::<Vector3<f64>>()
                .into();
            // `t − β₀`, and `β₀ ≤ 0` as `t ≤ t − β₀`.
            let rise = depth - (start - pose.tip).dot(&z);
            let went_over = depth <= rise
                && rise <= advance
                && front_face_ahead(s, surface, pose, radius / GRAZING, x);
            went_over.then_some(-n)
        });
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
            let off_axis = (x[vi] - pose.tip).cross(&z).norm();
            if s.fixed[vi] || off_axis > radius + MAX_STRETCH * s.span[vi] {
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

/// Whether the ray from the tip away from the handle meets, within `reach`, a face
/// toward the handle: the front face the tip presses, which a back face that went
/// over the tip has crossed (see the module notes). A tip inside the tissue, which
/// has no such face ahead of it, leaves through the back face instead.
fn front_face_ahead(
    s: &Scratch,
    surface: &Surface,
    pose: &InstrumentPose,
    reach: f64,
    x: &[Point3<f64>],
) -> bool {
    let ahead = -pose.axis.into_inner();
    s.triangles.iter().any(|&t| {
        let p = surface.triangles[t as usize].map(|v| x[v as usize]);
        let faces_handle = (p[1] - p[0]).cross(&(p[2] - p[0])).dot(&ahead) < 0.0;
        faces_handle && ray_triangle(&pose.tip, &ahead, &p).is_some_and(|hit| hit.t <= reach)
    })
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

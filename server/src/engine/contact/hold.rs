//! Whether a held vertex stays held, slides or is let go: Coulomb's law on the
//! instrument's surface, with adhesion, and where the tip's hold beside the shaft
//! ends. Plain data in, a [`Hold`] out; the contact stage applies it
//! (`ContactStage::hold_and_release`).

use nalgebra::{Point3, Vector3};

use super::closest::{TrianglePoint, closest_point_triangle, closest_triangle_axis};
use super::pose::InstrumentPose;
use crate::engine::mesh::Surface;

/// The pull-away a held vertex withstands, as a fraction of the mean force on its
/// instrument's held vertices. Without it, vertices on the flanks of a shaft pushed
/// sideways — where the push-out puts them back on the cylinder with the tissue
/// pulling them very slightly away — were released and re-taken every other tick,
/// and the force flickered by 12%. Wet tissue sticks that much; a withdrawing
/// instrument pulls far harder.
pub(super) const ADHESION: f64 = 0.1;

/// The adhesion of an instrument, N: [`ADHESION`] times the mean of `reactions`, the
/// norms of the tissue's reactions on its held vertices (0 when it holds none).
pub(super) fn adhesion(reactions: impl Iterator<Item = f64>) -> f64 {
    let (sum, count) = reactions.fold((0.0, 0usize), |(s, n), r| (s + r, n + 1));
    ADHESION * (sum / count.max(1) as f64)
}

/// The normal part of Coulomb's law with adhesion: whether a held vertex the tissue
/// pushes onto the instrument with `normal = N = −reaction·m` (negative: pulls it
/// away) is let go. Without adhesion a vertex the tissue no longer presses goes too.
pub(super) fn pulled_away(normal: f64, adhesion: f64) -> bool {
    normal < -adhesion || (normal <= 0.0 && adhesion == 0.0)
}

/// The longest slide of a held vertex in one tick, as a fraction of the radius.
pub(super) const MAX_SLIDE: f64 = 0.5;

/// The shortest slide made, as a fraction of the radius (5 µm on a 5 mm shaft). The
/// slide is a step of the excess drag over the vertex's own stiffness `K_ii`, stiffer
/// than the tissue around it, so successive slides close in on the friction cone
/// geometrically and never quite reach it; each moves the held vertex off the chords
/// the push-out left its edges on, and the push-out puts them back. Below this the
/// slides only stirred those margins (10 µm of push-out every other tick, a residual
/// of a millinewton that never died out); the drag they leave is `K_ii` times 5 µm,
/// a few hundredths of a percent of the force.
pub(super) const MIN_SLIDE: f64 = 1e-3;

/// What becomes of a held vertex this tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Hold {
    /// Pressed on and within friction: it stays where it is on the instrument.
    Stick,
    /// Pressed on but dragged harder than friction allows: it slides along the
    /// instrument's surface in direction `t̂` until the drag falls by the excess, N.
    Slip(nalgebra::Unit<Vector3<f64>>, f64),
    /// Pulled away: the tissue takes it back.
    Release,
}

/// Coulomb's law on the instrument's surface for a held vertex at `x` on which the
/// tissue exerts `reaction`.
///
/// `m` is the instrument's outward surface normal at the vertex: `−Z` for a vertex at
/// or beyond the tip of an instrument whose tip presses (§2.5 lays the tip triangle on
/// the plane ⊥ Z ahead of the tip: a flat end), else the radial direction from the
/// axis. The tissue pushes the vertex onto the instrument with `N = −reaction·m`; the
/// rest, `T`, is tangential. `N < −adhesion`: pulled away, released, the tissue
/// relaxes.
/// `|T| ≤ μ N`: it sticks. Otherwise it slips along `T` (the return mapping of
/// friction: slide until the drag is on the cone). Without the friction bound a held
/// vertex followed the instrument whatever the tissue's pull, so that a slid or
/// withdrawn instrument kept dragging tissue it no longer pressed; releasing a
/// slipping vertex instead of sliding it made it flip between held and free every
/// other tick under a steady sideways push.
///
/// Off the instrument's body — on the tip's end further than [`OFF_SHAFT`]·r from
/// the axis — a vertex touches no part of the instrument: it lies on the tip plane
/// only because the tip press laid its whole triangle there (a coarse mesh cannot
/// bend around the tip). It stays held only while the tip still presses on that
/// triangle or another of the vertex's triangles: one of them within
/// [`TIP_REACH`]·r of the tip `P` (a triangle laid on the tip plane is at `r`).
/// Without this a tip withdrawn after a slide kept tissue it had dragged sideways,
/// six radii from its axis and a centimetre out of the liver, with 0.7 N: on the
/// unbounded tip plane, whose normal is `−Z`, the tissue's sideways pull counted as
/// a push on the tip's end.
///
/// Beside the shaft, a vertex held off its surface (further than [`OFF_SHAFT`]·r from
/// the axis, as the ends of an edge the shaft pushed out are) stays held only while
/// the shaft still presses one of its triangles ([`shaft_press`]). Without this a
/// vertex the tip had laid on its end, carried beside the shaft when the instrument
/// turned, was taken for one the shaft pressed: after deep, fast swings of both
/// instruments through the liver the withdrawn instruments went on holding vertices
/// 10–47 cm from their axes, the liver half a metre out with 150–330 N.
///
/// Such a vertex slides in the plane it was laid on. The tip press laid its triangle
/// on the plane through `P − r·n_prox` normal to `n_prox` (see `tip`), at distance
/// `r` from `P`; while the tip's nearest point `c` on the nearest of the vertex's
/// triangles lies inside that triangle (the triangle flat against the tip,
/// [`TipPress::flat`]), the slide loses its component along `ĉ = (c − P)/|c − P|`
/// (`= −n_prox` while the triangle lies on that plane). Coulomb's law itself keeps
/// `−Z`. Without the projection, slides perpendicular to `Z` moved the triangle off
/// its plane, away from the tip when the axis is tilted to the surface: after a
/// 20 mm slide on SOFA's liver, a withdrawal at 60 Hz slid the held triangle from
/// 5.00 to 5.21 mm from the tip in six ticks, past [`OFF_SHAFT`]·r, and let all three
/// vertices go while the tissue still pressed one of them with 1.5 N; the tissue
/// sprang back 7 mm and was caught again the next tick with a 0.3 N spike, at a time
/// set by the tick (the workspace's `tests/tests/reaction_rate.rs`). Taking `ĉ` for
/// the normal of the law instead upset the frictionless tip in the Hertz blocks
/// (`tests/contact_footprint.rs`): for the vertices off the body only, the contact
/// set still shifted after 40 passes; for those on the tip's end too, the coarse
/// block's force rose to 1.31× the fine one's.
pub(super) fn stays_held(
    x: &Point3<f64>,
    reaction: &Vector3<f64>,
    pose: &InstrumentPose,
    (length, radius): (f64, f64),
    (tip_contact, friction, adhesion): (bool, f64, f64),
    pressed_by_tip: impl FnOnce() -> Option<TipPress>,
    pressed_by_shaft: impl FnOnce() -> bool,
) -> Hold {
    let Some((m, on_body)) = contact_normal(x, pose, length, radius, tip_contact) else {
        return Hold::Release;
    };
    if on_body
        && super::closest::closest_point_axis(x, pose, length).distance() > OFF_SHAFT * radius
        && !pressed_by_shaft()
    {
        return Hold::Release;
    }
    let flat = if on_body {
        None
    } else {
        match pressed_by_tip() {
            Some(press) => press.flat,
            None => return Hold::Release,
        }
    };
    let normal = -reaction.dot(&m);
    if pulled_away(normal, adhesion) {
        return Hold::Release;
    }
    let normal = normal.max(0.0);
    let tangential = reaction + m * normal;
    let excess = tangential.norm() - friction * normal;
    let along = match flat {
        Some(c) => tangential - c * tangential.dot(&c),
        None => tangential,
    };
    match nalgebra::Unit::try_new(along, 0.0) {
        Some(t) if excess > 0.0 => Hold::Slip(t, excess),
        _ => Hold::Stick,
    }
}

/// The instrument's outward surface normal `m` at a held vertex `x`: `−Z` on the
/// tip's flat end, else the radial direction from the axis; `None` on the axis. With
/// it, whether `x` is on the instrument's body: not on the tip's end further than
/// [`OFF_SHAFT`]·r from the axis.
///
/// The tip's end is where the vertex lies at or beyond the tip (`β ≤ 0`), and, with
/// a pressing tip, also where it lies off the shaft's surface (beyond
/// [`OFF_SHAFT`]·r from the axis) level with the tip (`(x − P)·Z ≤ r`, the split of
/// the local model): the tip press lays the whole triangle under the tip on its
/// plane, so on a coarse mesh it holds vertices a centimetre or two beside the
/// shaft. Those touch no part of the shaft; taking the radial direction for them
/// made a withdrawal along the axis look like a slide along the shaft, and they
/// crept toward the tip a few hundred microns a tick, held for half a second.
pub fn contact_normal(
    x: &Point3<f64>,
    pose: &InstrumentPose,
    length: f64,
    radius: f64,
    tip_contact: bool,
) -> Option<(Vector3<f64>, bool)> {
    let c = super::closest::closest_point_axis(x, pose, length);
    let level = (x - pose.tip).dot(&pose.axis);
    let off_shaft = c.distance() > OFF_SHAFT * radius;
    let at_tip = (c.beta <= 0.0 && level <= 0.0) || (off_shaft && level <= radius);
    if at_tip && tip_contact {
        Some((-pose.axis.into_inner(), !off_shaft))
    } else {
        c.offset.try_normalize(0.0).map(|m| (m, true))
    }
}

/// How the tip presses on a triangle of a held vertex ([`tip_press`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct TipPress {
    /// `ĉ = (c − P)/|c − P|`, from the tip `P` to `c`, the nearest point of the nearest
    /// of the vertex's triangles, when `c` lies inside that triangle: the triangle lies
    /// flat against the tip, normal to `ĉ`. `None` when `c` is on one of its sides or
    /// corners, where `ĉ` is no normal of the triangle and turns as the vertex moves.
    flat: Option<Vector3<f64>>,
}

/// Whether the tip `P` still presses on one of surface vertex `v`'s triangles: one
/// of them within [`TIP_REACH`]·r of it; if so, how.
pub(super) fn tip_press(
    surface: &Surface,
    v: u32,
    tip: &Point3<f64>,
    radius: f64,
    x: &[Point3<f64>],
) -> Option<TipPress> {
    let slot = surface.slot(v)?;
    let nearest = surface
        .triangles_around(slot)
        .iter()
        .map(|&t| {
            let tri = surface.triangles[t as usize].map(|w| x[w as usize]);
            closest_point_triangle(tip, &tri)
        })
        .min_by(|a, b| {
            let d = |c: &TrianglePoint| (c.point - tip).norm_squared();
            d(a).total_cmp(&d(b))
        })?;
    let offset = nearest.point - tip;
    (offset.norm() <= TIP_REACH * radius).then(|| TipPress {
        flat: nearest
            .barycentric
            .iter()
            .all(|&w| w > FLAT_MARGIN)
            .then(|| offset.try_normalize(0.0))
            .flatten(),
    })
}

/// Whether the shaft (the axis segment of `length`) still presses one of surface
/// vertex `v`'s triangles: one of them within [`OFF_SHAFT`]·r of the axis.
pub(super) fn shaft_press(
    surface: &Surface,
    v: u32,
    pose: &InstrumentPose,
    length: f64,
    radius: f64,
    x: &[Point3<f64>],
) -> bool {
    let Some(slot) = surface.slot(v) else {
        return false;
    };
    surface.triangles_around(slot).iter().any(|&t| {
        let tri = surface.triangles[t as usize].map(|w| x[w as usize]);
        closest_triangle_axis(&tri, pose, length).distance() <= OFF_SHAFT * radius
    })
}

/// Smallest barycentric coordinate of the tip's nearest point for a triangle to lie
/// flat against the tip ([`TipPress::flat`]). `closest_point_triangle` gives exact
/// zeros on a side or corner; the margin (a thousandth of the triangle) keeps a
/// nearest point that lies on a side up to round-off from counting as inside.
const FLAT_MARGIN: f64 = 1e-3;

/// Distance from the tip `P`, in radii, within which one of a held vertex's triangles
/// must lie for the tip to still press it ([`tip_press`]), when the vertex is off the
/// instrument's body.
///
/// The tip press lays the triangle under the tip at `r` from `P`, but keeps only the
/// vertices the tissue presses on the tip: a vertex of that triangle that the tissue
/// pulls away is let go, and the triangle then turns about its held edge as that
/// vertex follows the tissue. The README's press (3.5 cm into the coarse liver) on
/// nearly incompressible tissue (ν = 0.499) turned it from 5.00 to 5.61 mm (1.12 r)
/// from the tip, while the tissue pressed the two held vertices on it with 0.8 and
/// 1.9 N. With the bound at [`OFF_SHAFT`] (1.05 r) both were let go 5 mm into the
/// press and caught again with a jump the next tick, and the held set went on cycling
/// between 3 and 0 vertices every few ticks to the end of the hold: 30–65 N on each
/// retake where the hold is 2.76 N, 44–76 N stepped explicitly
/// (`tests/explicit_chatter.rs`). 1.25 r covered that turn, but not the one after a
/// tick that lets go the vertices a settled jump pulls (`release_pulled`): the
/// relaxation that follows turned the tip's triangle to 6.60 mm (1.32 r) on a
/// first pose 3 cm into the coarse liver, and the next tick let the whole hold go,
/// a tick with no force between 1.06 N ones (`tests/contact_first_touch.rs`). Half a
/// radius more covers both turns; what the bound is for, tissue dragged six radii
/// from the tip by a slide and withdrawn, is still far outside it.
pub(super) const TIP_REACH: f64 = 1.5;

/// Distance from the axis, in radii, beyond which a held vertex is off the shaft's
/// surface: the push-out leaves vertices at `r (1 + 10⁻⁴)` and an edge pushed out
/// leaves its ends a little further; 1.05 r is well clear of both.
pub(super) const OFF_SHAFT: f64 = 1.05;

//! Where a gesture aims, read from the scene the server describes.

use nalgebra::Point3;

use crate::proto::v1::{InstrumentDescription, SceneDescription};

/// The rest-surface positions of `scene`, m (none for a scene without surface).
fn rest_points(scene: &SceneDescription) -> impl Iterator<Item = Point3<f64>> + Clone + '_ {
    scene
        .rest_surface
        .as_ref()
        .map(|s| s.positions.as_slice())
        .unwrap_or_default()
        .chunks_exact(3)
        .map(|p| Point3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])))
}

/// The rest-surface vertex nearest to `point`; `None` for a scene without surface.
///
/// No surface point is nearer `point` than that vertex's nearest point on the
/// surface, so the open segment from a trocar to its nearest vertex crosses no
/// surface: an instrument moving along that line touches the liver there first.
pub fn nearest_surface_vertex(
    scene: &SceneDescription,
    point: &Point3<f64>,
) -> Option<Point3<f64>> {
    scene.rest_surface.as_ref()?;
    rest_points(scene)
        .filter(|p| p.coords.iter().all(|c| c.is_finite()))
        .min_by(|a, b| {
            let da = (a - point).norm_squared();
            let db = (b - point).norm_squared();
            da.total_cmp(&db)
        })
}

/// The most forward (+z) of `points` near the middle (|x| < 3 cm, |y| < 2 cm): on
/// the default liver, a point of its free front face. `None` when no point is near
/// the middle.
pub fn front_middle(points: impl IntoIterator<Item = Point3<f64>>) -> Option<Point3<f64>> {
    points
        .into_iter()
        .filter(|p| p.x.abs() < 0.03 && p.y.abs() < 0.02)
        .max_by(|a, b| a.z.total_cmp(&b.z))
}

/// The front point of `scene`'s rest surface: [`front_middle`] of its vertices, or
/// the most forward vertex of all, or the origin for a scene without surface.
pub fn front(scene: &SceneDescription) -> Point3<f64> {
    let points = rest_points(scene);
    front_middle(points.clone())
        .or_else(|| points.max_by(|a, b| a.z.total_cmp(&b.z)))
        .unwrap_or_else(Point3::origin)
}

/// The instrument's trocar, m (the origin when the scene leaves it out).
pub fn trocar(instrument: &InstrumentDescription) -> Point3<f64> {
    instrument
        .trocar
        .as_ref()
        .map_or_else(Point3::origin, |v| Point3::new(v.x, v.y, v.z))
}

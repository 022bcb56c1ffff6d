//! The held vertices as the live stream sends them (`InstrumentState.
//! held_surface_vertices`): while an instrument presses the liver, as many
//! distinct surface vertex numbers as `held_vertex_count`, each naming a vertex
//! of the surface frame of the same tick that lies against the instrument or at
//! the far end of an edge that does (the contact stage pushes edges and holds
//! both their ends).

use std::collections::HashSet;

use laparo_proto::v1;
use laparo_proto::v1::server_message::Kind;
use laparo_server::service::ServeConfig;
use laparo_tests::pressing::*;
use laparo_tests::server::*;

/// Distance from `p` to the segment from `a` to `b`, m.
fn to_segment(p: [f64; 3], a: [f64; 3], b: [f64; 3]) -> f64 {
    let ab = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let ap = [p[0] - a[0], p[1] - a[1], p[2] - a[2]];
    let len2 = ab.iter().map(|x| x * x).sum::<f64>();
    let t = (ap.iter().zip(&ab).map(|(x, y)| x * y).sum::<f64>() / len2).clamp(0.0, 1.0);
    let d = [ap[0] - t * ab[0], ap[1] - t * ab[1], ap[2] - t * ab[2]];
    d.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Length of the longest surface edge at vertex `v`, m, at the positions `at`.
fn longest_edge(triangles: &[u32], v: u32, at: &impl Fn(u32) -> [f64; 3]) -> f64 {
    let p = at(v);
    let mut longest: f64 = 0.0;
    for t in triangles.chunks_exact(3) {
        if t.contains(&v) {
            for &w in t {
                let q = at(w);
                longest = longest.max(
                    ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt(),
                );
            }
        }
    }
    longest
}

/// How far a held vertex may lie outside the instrument's radius, m: the holds
/// follow the instrument a tick late (the press below moves under 1 mm a tick),
/// and positions travel as f32.
const SLACK_M: f64 = 2e-3;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_stream_names_each_held_vertex_and_it_lies_against_the_instrument() {
    let server = TestServer::start(ServeConfig::default()).await;
    let ch = server.channel().await;
    let session = create_session(ch.clone(), None).await.unwrap().session_id;
    let (mut station, joined) = join(ch.clone(), None, &session, &["left"]).await.unwrap();
    let scene = joined.scene.as_ref().unwrap();
    let surface_vertices = scene.rest_surface.as_ref().unwrap().positions.len() / 3;
    let left = scene.instruments.iter().find(|i| i.name == "left").unwrap();
    let (radius, length) = (left.radius_m, left.length_m);
    let triangles = scene.rest_surface.as_ref().unwrap().triangles.clone();
    press(&station, "left", front(&joined), 0.0);

    let mut surface: Option<v1::SurfaceFrame> = None;
    let mut checked = 0;
    let checked_enough = wait_for(&mut station.rx, WAIT, |m| {
        match &m.kind {
            Some(Kind::SurfaceFrame(f)) => surface = Some(f.clone()),
            Some(Kind::InstrumentState(s)) if s.instrument == "left" => {
                let held = &s.held_surface_vertices;
                assert_eq!(held.len(), s.held_vertex_count as usize, "{s:?}");
                let distinct: HashSet<_> = held.iter().collect();
                assert_eq!(distinct.len(), held.len(), "{held:?}");
                assert!(held.iter().all(|&v| (v as usize) < surface_vertices));
                let Some(f) = surface.as_ref().filter(|f| f.tick == s.tick) else {
                    return false;
                };
                let (Some(pose), false) = (s.pose.as_ref(), held.is_empty()) else {
                    return false;
                };
                let (tip, axis) = (pose.tip.unwrap(), pose.axis.unwrap());
                let a = [tip.x, tip.y, tip.z];
                let b = [
                    tip.x + length * axis.x,
                    tip.y + length * axis.y,
                    tip.z + length * axis.z,
                ];
                // The stage pushes edges out of the cylinder, and holds both
                // ends of each: a held vertex lies against the instrument, or
                // at most its longest edge away.
                let at = |v: u32| {
                    let i = 3 * v as usize;
                    [f.positions[i] as f64, f.positions[i + 1] as f64, f.positions[i + 2] as f64]
                };
                let mut nearest = f64::INFINITY;
                for &v in held {
                    let d = to_segment(at(v), a, b);
                    nearest = nearest.min(d);
                    let reach = longest_edge(&triangles, v, &at);
                    assert!(
                        d <= radius + reach + SLACK_M,
                        "held vertex {v} at {d} m from the instrument's axis (radius {radius} m, longest edge {reach} m), tick {}",
                        s.tick
                    );
                }
                assert!(nearest <= radius + SLACK_M, "no held vertex against the instrument: nearest {nearest} m, tick {}", s.tick);
                checked += 1;
                return checked >= 20;
            }
            _ => {}
        }
        false
    })
    .await;
    assert!(
        checked_enough.is_some(),
        "only {checked} states with held vertices and their tick's surface"
    );
    server.shutdown().await.unwrap();
}

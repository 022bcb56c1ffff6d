//! What recording costs a session: mechanics tick time with and without a recorder,
//! in the same run, and the bytes a recording takes per simulated minute.
//!
//! For each mesh, two sessions of the same scene run side by side on their own
//! mechanics threads, one recorded and one not, driven by the same probe (the tip
//! pressing the front face, sliding and withdrawing, repeated) from a 1 kHz
//! driver, the poses handed to both and recorded by the first as a station's
//! would be. Once a second each session's last-second tick p50 and p99 are read;
//! the table gives the medians of those per-second figures, their ratio, missed
//! deadlines, and the recording's size and recorder backlog and lag at the end.
//! Side by side, both sessions see the same machine; on two cores the recorder
//! thread competes with both mechanics threads and the driver.
//!
//! `cargo bench -p laparo-tests --bench recording` (`LAPARO_MESH_DIR` to find
//! liver-20k, default `../shared/data/liver`; `LAPARO_BENCH_SECONDS`, default 20;
//! `LAPARO_BENCH_KEEP=DIR` keeps the recordings in DIR).

use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use laparo_client::gestures::PROBE_SECONDS;
use laparo_proto::force::wire::to_pose;
use laparo_proto::v1;
use laparo_server::engine::contact::InstrumentPose;
use laparo_server::engine::scene::Scene;
use laparo_server::session::{PoseIn, Session, SessionConfig};
use laparo_tests::coupled::front_probe;

fn shared_mesh(label: &str) -> Option<PathBuf> {
    let dir = std::env::var_os("LAPARO_MESH_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/../../shared/data/liver"
            ))
        });
    let path = dir.join(format!("{label}.msh"));
    if path.exists() {
        Some(path)
    } else {
        eprintln!("skipping {label}: {} not found", path.display());
        None
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        f64::NAN
    } else {
        v[v.len() / 2]
    }
}

struct Row {
    label: &'static str,
    surface_vertices: usize,
    rate_hz: f64,
    p50: [f64; 2],
    p99: [f64; 2],
    missed: [u64; 2],
    sim_s: f64,
    bytes: u64,
    poses: u64,
    dropped: u64,
    backlog: u64,
    lag_ms: f64,
}

fn run(label: &'static str, scene: Scene, seconds: f64) -> Row {
    // LAPARO_BENCH_KEEP=DIR keeps the recordings there, to look into them.
    let keep = std::env::var_os("LAPARO_BENCH_KEEP").map(PathBuf::from);
    let dir = keep.clone().unwrap_or_else(|| {
        std::env::temp_dir().join(format!("laparo-bench-rec-{}-{label}", std::process::id()))
    });
    if keep.is_none() {
        let _ = std::fs::remove_dir_all(&dir);
    }
    std::fs::create_dir_all(&dir).expect("a temporary folder");
    let recorded = Session::start(
        format!("rec-{label}"),
        scene.clone(),
        &SessionConfig {
            idle_timeout: None,
            recordings: Some(dir.clone()),
        },
    )
    .expect("the scene builds");
    let plain = Session::start(
        format!("plain-{label}"),
        scene.clone(),
        &SessionConfig {
            idle_timeout: None,
            recordings: None,
        },
    )
    .expect("the scene builds");
    let sim = scene.build().expect("the scene builds");
    let probe = front_probe(&sim, 0.008, 0.02);
    let name = sim.instruments[0].name.clone();
    let rate_hz = scene.mechanics.rate_hz;
    let surface_vertices = sim.mesh.surface.vertices.len();
    drop(sim);

    let sessions = [recorded.clone(), plain.clone()];
    let driver = {
        let sessions = sessions.clone();
        std::thread::spawn(move || {
            let start = Instant::now();
            let mut k = 0u64;
            let mut poses = 0u64;
            while start.elapsed().as_secs_f64() < seconds {
                let t = k as f64 * 1e-3;
                let (tip, axis) = probe.pose(t % PROBE_SECONDS);
                let pose = InstrumentPose::new(tip, axis);
                k += 1;
                for s in &sessions {
                    s.submit_pose(
                        0,
                        PoseIn {
                            pose,
                            sequence: k,
                            station: 1,
                        },
                    );
                }
                sessions[0].record_pose(&v1::DevicePose {
                    instrument: name.clone(),
                    pose: Some(to_pose(&tip, &axis)),
                    device_time_s: t,
                    sequence: k,
                });
                poses += 1;
                let next = start + Duration::from_secs_f64(k as f64 * 1e-3);
                if let Some(wait) = next.checked_duration_since(Instant::now()) {
                    std::thread::sleep(wait);
                }
            }
            poses
        })
    };
    let (mut p50, mut p99) = ([vec![], vec![]], [vec![], vec![]]);
    let start = Instant::now();
    // The first second warms up (and has no tick figures yet).
    std::thread::sleep(Duration::from_millis(1500));
    while start.elapsed().as_secs_f64() < seconds {
        for (i, s) in sessions.iter().enumerate() {
            let info = s.info();
            p50[i].push(info.tick_time_p50_ms);
            p99[i].push(info.tick_time_p99_ms);
        }
        std::thread::sleep(Duration::from_secs(1));
    }
    let poses = driver.join().expect("the driver ran");
    let infos = [recorded.info(), plain.info()];
    for s in &sessions {
        s.close("bench over");
        s.join();
    }
    let file = dir.join(infos[0].recording_file.clone().expect("recorded"));
    let bytes = std::fs::metadata(&file).map(|m| m.len()).unwrap_or(0);
    let stats = recorded.recorder().expect("recorded").stats();
    let row = Row {
        label,
        surface_vertices,
        rate_hz,
        p50: [median(p50[0].clone()), median(p50[1].clone())],
        p99: [median(p99[0].clone()), median(p99[1].clone())],
        missed: [infos[0].missed_deadlines, infos[1].missed_deadlines],
        sim_s: f64::from_bits(recorded.stats.sim_time_bits.load(Ordering::Relaxed)),
        bytes,
        poses,
        dropped: stats.dropped.load(Ordering::Relaxed),
        backlog: stats.max_backlog.load(Ordering::Relaxed),
        lag_ms: stats.max_lag_us.load(Ordering::Relaxed) as f64 * 1e-3,
    };
    if keep.is_none() {
        let _ = std::fs::remove_dir_all(&dir);
    }
    row
}

fn main() {
    let seconds: f64 = std::env::var("LAPARO_BENCH_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(20.0);
    let mut rows = vec![run("default", Scene::default_scene(), seconds)];
    if let Some(path) = shared_mesh("liver-20k") {
        let mut scene = Scene::default_scene();
        scene.mesh.file = path.display().to_string();
        rows.push(run("liver-20k", scene, seconds));
    }
    println!(
        "\nTwo sessions side by side per mesh, one recorded, one not; {seconds} s wall, probe poses at 1 kHz to both.\n"
    );
    println!(
        "| mesh | surface vertices | rate (Hz) | tick p50 recorded / not (ms) | ratio | tick p99 recorded / not (ms) | missed recorded / not | simulated (s) | poses recorded | bytes | MB per simulated minute | recorder dropped | max backlog | max lag (ms) |"
    );
    println!("|---|---:|---:|---|---:|---|---|---:|---:|---:|---:|---:|---:|---:|");
    for r in rows {
        println!(
            "| {} | {} | {} | {:.3} / {:.3} | {:.2} | {:.3} / {:.3} | {} / {} | {:.1} | {} | {} | {:.2} | {} | {} | {:.1} |",
            r.label,
            r.surface_vertices,
            r.rate_hz,
            r.p50[0],
            r.p50[1],
            r.p50[0] / r.p50[1],
            r.p99[0],
            r.p99[1],
            r.missed[0],
            r.missed[1],
            r.sim_s,
            r.poses,
            r.bytes,
            r.bytes as f64 / r.sim_s * 60.0 / 1e6,
            r.dropped,
            r.backlog,
            r.lag_ms
        );
    }
}

use nalgebra::Point3;

use super::*;
use crate::engine::mesh::TetMesh;
use crate::engine::scene::Scene;

/// The default scene's settings on a single tetrahedron: frames of a few hundred bytes.
fn one_tetrahedron() -> Simulation {
    let positions = vec![
        Point3::new(0.0, 0.0, 0.0),
        Point3::new(0.1, 0.0, 0.0),
        Point3::new(0.0, 0.1, 0.0),
        Point3::new(0.0, 0.0, 0.1),
    ];
    let mesh = TetMesh::from_tets(positions, vec![[0, 1, 2, 3]]).unwrap();
    let mut scene = Scene::default_scene();
    scene.fixed.boxes.clear();
    scene.fixed.nodes = vec![0];
    scene.build_on(mesh).unwrap()
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("laparo-pvd-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The `(timestep, file)` of each `<DataSet>` of a complete index, which must be
/// exactly the header, one line a frame and the closing tags.
fn datasets(index: &str) -> Vec<(f64, String)> {
    let body = index
        .strip_prefix(HEAD)
        .unwrap_or_else(|| panic!("no header: {index}"))
        .strip_suffix(TAIL)
        .unwrap_or_else(|| panic!("not closed: {index}"));
    body.lines()
        .map(|line| {
            let attr = |name: &str| {
                let start = line.find(&format!("{name}=\"")).unwrap() + name.len() + 2;
                line[start..start + line[start..].find('"').unwrap()].to_string()
            };
            assert!(line.trim_start().starts_with("<DataSet "), "{line}");
            (attr("timestep").parse().unwrap(), attr("file"))
        })
        .collect()
}

#[test]
fn after_every_frame_the_index_lists_exactly_the_frames_written_in_order() {
    let dir = temp_dir("list");
    let path = dir.join("run.pvd");
    let mut sim = one_tetrahedron();
    let mut series = PvdSeries::new(&path);
    let mut expected = Vec::new();
    for k in 0..120 {
        sim.time = k as f64 * 0.0125;
        series.write_frame(&sim).unwrap();
        expected.push((sim.time, format!("run_{k:06}.vtu")));
        // What a run killed now would leave.
        assert_eq!(datasets(&std::fs::read_to_string(&path).unwrap()), expected);
    }
    assert_eq!(series.len(), 120);
    assert!(series.files().iter().all(|f| f.exists()));
    // A new series over the same path starts afresh.
    let mut again = PvdSeries::new(&path);
    again.write_frame(&sim).unwrap();
    assert_eq!(
        datasets(&std::fs::read_to_string(&path).unwrap()),
        vec![(sim.time, "run_000000.vtu".to_string())]
    );
    std::fs::remove_dir_all(dir).unwrap();
}

/// Bytes this thread has passed to `write` so far (Linux's per-thread I/O
/// accounting): a test runs on a thread of its own.
#[cfg(target_os = "linux")]
fn written_by_this_thread() -> u64 {
    let io = std::fs::read_to_string("/proc/thread-self/io").unwrap();
    io.lines()
        .find_map(|l| l.strip_prefix("wchar:"))
        .unwrap()
        .trim()
        .parse()
        .unwrap()
}

#[cfg(target_os = "linux")]
#[test]
fn the_bytes_a_frame_writes_to_the_index_do_not_grow_with_the_frame_count() {
    let dir = temp_dir("bytes");
    let path = dir.join("s.pvd");
    let mut sim = one_tetrahedron();
    let mut series = PvdSeries::new(&path);
    let mut index_bytes = Vec::new();
    for k in 0..600 {
        sim.time = k as f64 * 1e-4;
        let before = written_by_this_thread();
        series.write_frame(&sim).unwrap();
        let vtu = std::fs::metadata(dir.join(format!("s_{k:06}.vtu")))
            .unwrap()
            .len();
        index_bytes.push(written_by_this_thread() - before - vtu);
    }
    // A frame's line and the closing tags (the first frame also the header): the
    // same few hundred bytes at frame 599 as at frame 1, not the whole index.
    // (A time takes at most 24 characters in `{:e}`: `-1.2345678901234567e-308`.)
    let line = r#"    <DataSet timestep="" group="" part="0" file="s_000599.vtu"/>"#;
    let bound = (line.len() + 24 + 1 + TAIL.len()) as u64;
    assert!(
        index_bytes[0] <= HEAD.len() as u64 + bound,
        "{}",
        index_bytes[0]
    );
    for (k, &b) in index_bytes.iter().enumerate().skip(1) {
        assert!(
            b <= bound,
            "frame {k} wrote {b} bytes to the index (bound {bound})"
        );
    }
    assert_eq!(
        datasets(&std::fs::read_to_string(&path).unwrap()).len(),
        600
    );
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn a_series_may_write_exactly_its_six_digit_frames_beside_it() {
    let dir = temp_dir("may-write");
    let series = PvdSeries::new(&dir.join("s.pvd"));
    for ok in ["s_000000.vtu", "s_000001.vtu", "s_099999.vtu"] {
        assert!(series.may_write(&dir.join(ok)), "{ok}");
    }
    for other in [
        "s_00001.vtu",
        "s_0000001.vtu",
        "s_+00001.vtu",
        "s_-00001.vtu",
        "s_ 00001.vtu",
        "s_100000.vtu",
        "s_000001.vtk",
        "t_000001.vtu",
        "s000001.vtu",
        "s.pvd",
    ] {
        assert!(!series.may_write(&dir.join(other)), "{other}");
    }
    // The same name in another folder is another file.
    let elsewhere = temp_dir("may-write-elsewhere");
    assert!(!series.may_write(&elsewhere.join("s_000001.vtu")));
    std::fs::remove_dir_all(&dir).unwrap();
    std::fs::remove_dir_all(&elsewhere).unwrap();
}

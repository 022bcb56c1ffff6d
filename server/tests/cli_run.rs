//! `laparo-server run`, end to end: the binary's export reads back to exactly the
//! state the library computes (the engine is deterministic and `{:e}` prints floats
//! so that they parse back to the same bits), and bad input fails cleanly.

use std::path::PathBuf;
use std::process::Command;

use laparo_server::engine::scene::Scene;
use laparo_server::export::vtu::tet_von_mises;
use laparo_server::headless;

fn server() -> Command {
    Command::new(env!("CARGO_BIN_EXE_laparo-server"))
}

/// Runs `command`, fails the test with its stderr unless it succeeds, and returns its
/// output.
fn succeed(command: &mut Command) -> std::process::Output {
    let out = command.output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Runs `command`, which must fail with status 1, and returns what it printed on
/// standard error.
fn fail(command: &mut Command) -> String {
    let out = command.output().unwrap();
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("laparo-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// The numbers of the `<DataArray ... Name="{name}" ...>` block of a VTU file.
fn data_array(vtu: &str, name: &str) -> Vec<f64> {
    let start = vtu
        .find(&format!("Name=\"{name}\""))
        .unwrap_or_else(|| panic!("no array {name}"));
    let body = &vtu[start..];
    let body = &body[body.find('>').unwrap() + 1..body.find("</DataArray>").unwrap()];
    body.split_whitespace()
        .map(|v| v.parse().unwrap())
        .collect()
}

#[test]
fn exported_state_matches_the_library_run_exactly() {
    let out = temp("default.vtu");
    let status = succeed(
        server()
            .args(["run", "--seconds", "0.5", "--export"])
            .arg(&out),
    );
    let stdout = String::from_utf8_lossy(&status.stdout);
    assert!(stdout.contains("ran 30 ticks"), "{stdout}");
    let vtu = std::fs::read_to_string(&out).unwrap();

    let mut sim = Scene::default_scene().build().unwrap();
    headless::run(&mut sim, 0.5, |_, _| {});
    let disp = data_array(&vtu, "displacement");
    assert_eq!(disp.len(), 3 * sim.mesh.vertex_count());
    for (i, (x, r)) in sim.state.x.iter().zip(&sim.model.rest).enumerate() {
        let u = x - r;
        assert_eq!(
            [disp[3 * i], disp[3 * i + 1], disp[3 * i + 2]],
            [u.x, u.y, u.z],
            "vertex {i}"
        );
    }
    assert_eq!(data_array(&vtu, "von_mises_stress"), tet_von_mises(&sim));
    let conn = data_array(&vtu, "connectivity");
    assert_eq!(conn.len(), 4 * sim.mesh.tets.len());
    assert!(vtu.contains(&format!(
        "NumberOfPoints=\"{}\" NumberOfCells=\"{}\"",
        sim.mesh.vertex_count(),
        sim.mesh.tets.len()
    )));
    // The liver sags under gravity: some stress, some displacement, nothing absurd.
    assert!(disp.iter().any(|&d| d != 0.0) && disp.iter().all(|d| d.abs() < 0.02));
}

#[test]
fn static_solve_of_the_sofa_demo_runs() {
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/sofa-liver.toml");
    let out = succeed(server().args(["run", "--static", "--scene", scene]));
    assert!(String::from_utf8_lossy(&out.stdout).contains("static: "));
}

#[test]
fn bad_input_fails_with_a_message_naming_it() {
    assert!(
        fail(server().args(["run", "--scene", "/no/such/scene.toml"]))
            .contains("/no/such/scene.toml")
    );

    let bad = temp("bad.toml");
    std::fs::write(&bad, "name = \"x\"\n[mesh]\nfile = \"builtin:liver.msh\"\n[material]\nyoung_modulus = 1.0\npoisson_ratio = 0.7\ndensity = 1.0\n").unwrap();
    assert!(fail(server().args(["run", "--scene"]).arg(&bad)).contains("material.poisson_ratio"));

    assert!(
        fail(server().args([
            "run",
            "--seconds",
            "0.1",
            "--export",
            "/no/such/dir/out.vtu",
        ]))
        .contains("/no/such/dir/out.vtu")
    );

    for args in [
        &["run", "--seconds", "nan"][..],
        &["run", "--seconds", "0"],
        &["run", "--static", "--seconds", "1"],
    ] {
        let out = server().args(args).output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?}");
    }
}

#[test]
fn trajectory_drives_the_instruments_and_bad_ones_are_named() {
    let csv = temp("press.csv");
    std::fs::write(
        &csv,
        "t,instrument,tip_x,tip_y,tip_z,axis_x,axis_y,axis_z\n\
         0.0, left, 0.0, 0.0, 0.09, 0, 0, 1\n\
         0.5, left, 0.0, 0.0, 0.055, 0, 0, 1\n\
         1.0, left, 0.0, 0.0, 0.055, 0, 0, 1\n",
    )
    .unwrap();
    let out = succeed(server().args(["run", "--trajectory"]).arg(&csv));
    let stdout = String::from_utf8_lossy(&out.stdout);
    // The run lasts as long as the trajectory, and the instrument holds tissue at the end.
    assert!(stdout.contains("ran 60 ticks"), "{stdout}");
    // Its tick times are order statistics of real ticks: 0 < median ≤ p99 ≤ max.
    let summary = stdout.lines().find(|l| l.starts_with("ran ")).unwrap();
    let ms = |after: &str| -> f64 {
        let at = summary.find(after).unwrap() + after.len();
        let value = summary[at..].split_whitespace().next().unwrap();
        value.parse().unwrap()
    };
    let (median, p99, max) = (ms("tick median "), ms("p99 "), ms("max "));
    assert!(0.0 < median && median <= p99 && p99 <= max, "{summary}");
    let last = stdout.lines().rfind(|l| l.starts_with("tick")).unwrap();
    assert!(
        last.contains("left: ") && !last.contains("left: 0 held"),
        "{last}"
    );

    std::fs::write(&csv, "0.0, scalpel, 0, 0, 0.09, 0, 0, 1\n").unwrap();
    assert!(fail(server().args(["run", "--trajectory"]).arg(&csv)).contains("`scalpel`"));

    // A keyframe beyond the longest run is refused by line, before any tick: a run
    // as long as 1e300 s once overflowed the tick count and aborted the process.
    std::fs::write(
        &csv,
        "0.0, left, 0, 0, 0.09, 0, 0, 1\n1e300, left, 0, 0, 0.09, 0, 0, 1\n",
    )
    .unwrap();
    let stderr = fail(server().args(["run", "--trajectory"]).arg(&csv));
    assert!(
        stderr.contains("press.csv:2:")
            && stderr.contains("time 1e300 s is beyond the 1e6 s a run may last"),
        "{stderr}"
    );
}

/// The `Points` block of a VTU file.
fn points(vtu: &str) -> Vec<f64> {
    let start = vtu.find("<Points>").expect("a Points block");
    let body = &vtu[start..];
    let body =
        &body[body.find("format=\"ascii\">").unwrap() + 15..body.find("</DataArray>").unwrap()];
    body.split_whitespace()
        .map(|v| v.parse().unwrap())
        .collect()
}

#[test]
fn a_time_series_lists_rest_points_and_displacements_at_each_period() {
    // 0.5 s at 60 Hz (30 ticks), a frame every 0.1 s: t = 0, 0.1, ..., 0.5 — six
    // frames, each with the rest points (so that Warp By Vector draws X + u) and the
    // last one with exactly the library's displacement after 30 ticks.
    let out = temp("series.pvd");
    succeed(
        server()
            .args(["run", "--seconds", "0.5", "--export-every", "0.1"])
            .arg(&out),
    );
    let pvd = std::fs::read_to_string(&out).unwrap();
    let times: Vec<f64> = pvd
        .match_indices("timestep=\"")
        .map(|(k, m)| {
            let rest = &pvd[k + m.len()..];
            rest[..rest.find('"').unwrap()].parse().unwrap()
        })
        .collect();
    assert_eq!(times.len(), 6, "{pvd}");
    for (k, t) in times.iter().enumerate() {
        assert!((t - 0.1 * k as f64).abs() < 1e-9, "frame {k} at {t}");
    }
    assert!(pvd.contains("file=\"series_000005.vtu\""), "{pvd}");
    let mut sim = Scene::default_scene().build().unwrap();
    let rest: Vec<f64> = sim
        .model
        .rest
        .iter()
        .flat_map(|p| [p.x, p.y, p.z])
        .collect();
    let first = std::fs::read_to_string(out.with_file_name("series_000000.vtu")).unwrap();
    assert_eq!(points(&first), rest);
    assert!(data_array(&first, "displacement").iter().all(|&d| d == 0.0));
    let last = std::fs::read_to_string(out.with_file_name("series_000005.vtu")).unwrap();
    assert_eq!(points(&last), rest);
    headless::run(&mut sim, 0.5, |_, _| {});
    let u: Vec<f64> = sim
        .state
        .x
        .iter()
        .zip(&sim.model.rest)
        .flat_map(|(x, r)| {
            let u = x - r;
            [u.x, u.y, u.z]
        })
        .collect();
    assert_eq!(data_array(&last, "displacement"), u);
}

#[test]
fn a_bad_series_period_or_folder_fails_with_a_message() {
    for period in ["0", "-1", "nan", "soon"] {
        let out = server()
            .args(["run", "--seconds", "0.1", "--export-every", period, "x.pvd"])
            .output()
            .unwrap();
        assert_ne!(out.status.code(), Some(0), "{period}");
        assert!(
            String::from_utf8_lossy(&out.stderr).contains(period),
            "{period}"
        );
    }
    assert!(
        fail(server().args([
            "run",
            "--seconds",
            "0.1",
            "--export-every",
            "0.05",
            "/no/such/dir/s.pvd",
        ]))
        .contains("/no/such/dir/s")
    );
    // Bytes that are not UTF-8: in the period, and in the series' name (its frames
    // are named after it in an XML index), each named in the message.
    use std::os::unix::ffi::OsStrExt;
    let bad = std::ffi::OsStr::from_bytes(b"\xff1.pvd");
    let said = fail(
        server()
            .args(["run", "--seconds", "0.1", "--export-every", "0.05"])
            .arg(bad),
    );
    assert!(
        said.contains("\u{fffd}1.pvd: the series' path must be UTF-8"),
        "{said}"
    );
    let said = fail(
        server()
            .args(["run", "--seconds", "0.1", "--export-every"])
            .arg(std::ffi::OsStr::from_bytes(b"0.\xff"))
            .arg("x.pvd"),
    );
    assert!(
        said.contains("the period is not a number of seconds"),
        "{said}"
    );
    // A single export into a folder that is not there is refused before the run
    // steps, not after it has run for nothing.
    let said = fail(server().args(["run", "--seconds", "0.5", "--export", "/no/such/dir/x.vtu"]));
    assert!(
        said.contains("there is no directory /no/such/dir to write it in"),
        "{said}"
    );
}

/// A single-tetrahedron Gmsh mesh, and a scene of it naming its mesh file `mesh`.
const ONE_TET_MSH: &str = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n\
    2 1 0 0\n3 0 1 0\n4 0 0 1\n$EndNodes\n$Elements\n1\n1 4 2 1 1 1 2 3 4\n$EndElements\n";

fn one_tet_scene(name: &str, mesh: &str) -> String {
    format!(
        "name = \"{name}\"\n[mesh]\nfile = \"{mesh}\"\nscale = 0.1\n\
         [material]\nyoung_modulus = 4500.0\npoisson_ratio = 0.45\ndensity = 1060.0\n\
         [fixed]\nnodes = [0]\n[mechanics]\nrate_hz = 1000.0\n"
    )
}

#[test]
fn an_export_named_as_another_kind_of_file_or_as_an_input_is_refused_and_nothing_written() {
    let dir = temp("inputs");
    std::fs::create_dir_all(&dir).unwrap();
    let (scene, mesh) = (dir.join("victim.toml"), dir.join("victim.msh"));
    std::fs::write(&mesh, ONE_TET_MSH).unwrap();
    std::fs::write(&scene, one_tet_scene("victim", "victim.msh")).unwrap();
    // Inputs under the names exports take: a scene, a mesh and a trajectory.
    let (scene_vtu, mesh_pvd, traj_vtu) = (
        dir.join("scene.vtu"),
        dir.join("mesh.pvd"),
        dir.join("traj.vtu"),
    );
    std::fs::write(&mesh_pvd, ONE_TET_MSH).unwrap();
    std::fs::write(&scene_vtu, one_tet_scene("s", "mesh.pvd")).unwrap();
    std::fs::write(&traj_vtu, "0, left, 0, 0, 0, 0, 0, 1\n").unwrap();
    let files = [&scene, &mesh, &scene_vtu, &mesh_pvd, &traj_vtu];
    let before: Vec<String> = files
        .iter()
        .map(|f| std::fs::read_to_string(f).unwrap())
        .collect();
    let s = |p: &PathBuf| p.to_str().unwrap().to_string();
    let cases: [(Vec<String>, &str); 6] = [
        (
            vec!["--scene".into(), s(&scene), "--export".into(), s(&scene)],
            ".vtu",
        ),
        (
            vec![
                "--scene".into(),
                s(&scene),
                "--export-every".into(),
                "0.001".into(),
                s(&mesh),
            ],
            ".pvd",
        ),
        (vec!["--export".into(), s(&dir.join("out"))], ".vtu"),
        (
            vec![
                "--scene".into(),
                s(&scene_vtu),
                "--export".into(),
                s(&scene_vtu),
            ],
            "scene file",
        ),
        (
            vec![
                "--scene".into(),
                s(&scene_vtu),
                "--export-every".into(),
                "0.01".into(),
                s(&mesh_pvd),
            ],
            "mesh file",
        ),
        (
            vec![
                "--trajectory".into(),
                s(&traj_vtu),
                "--export".into(),
                s(&traj_vtu),
            ],
            "trajectory file",
        ),
    ];
    for (args, what) in cases {
        let e = fail(server().arg("run").args(&args));
        assert!(
            e.contains(what) && e.contains(args.last().unwrap()),
            "{args:?}: {e}"
        );
    }
    for (f, text) in files.iter().zip(&before) {
        assert_eq!(
            &std::fs::read_to_string(f).unwrap(),
            text,
            "{}",
            f.display()
        );
    }
    // The same file reached through a symbolic link is the same file.
    #[cfg(unix)]
    {
        let link = dir.join("link.vtu");
        let _ = std::fs::remove_file(&link);
        std::os::unix::fs::symlink(&scene_vtu, &link).unwrap();
        let e = fail(server().args(["run", "--scene", &s(&scene_vtu), "--export", &s(&link)]));
        assert!(e.contains("scene file"), "{e}");
        assert_eq!(std::fs::read_to_string(&scene_vtu).unwrap(), before[2]);
    }
}

#[test]
fn a_scene_name_with_control_characters_is_printed_escaped() {
    let dir = temp("escapes");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("m.msh"), ONE_TET_MSH).unwrap();
    let scene = dir.join("esc.toml");
    // TOML escapes: ESC [2J (clear the screen) and a NUL in the name.
    std::fs::write(&scene, one_tet_scene(r"a\u001B[2Jb\u0000c", "m.msh")).unwrap();
    let out = succeed(
        server()
            .args(["run", "--seconds", "0.002", "--scene"])
            .arg(&scene),
    );
    let stdout = String::from_utf8(out.stdout).unwrap();
    assert!(
        !stdout.chars().any(|c| c.is_control() && c != '\n'),
        "{stdout:?}"
    );
    assert!(stdout.contains(r"scene a\u{1b}[2Jb\u{0}c:"), "{stdout}");
}

#[test]
fn a_tiny_series_period_is_refused_in_a_readable_message() {
    // At 60 Hz a frame every tick over 10^4 s: 600,001 frames (the start and each of
    // 600,000 ticks), refused before the run.
    let e = fail(server().args([
        "run",
        "--seconds",
        "10000",
        "--export-every",
        "1e-300",
        "x.pvd",
    ]));
    assert!(
        e.contains("--export-every 1e-300: 600001 frames over 10000 s (one every 1 ticks)"),
        "{e}"
    );
    assert!(e.len() < 200, "{} bytes: {e}", e.len());
}

/// The `(N frames)` of a run's `wrote OUT.pvd (N frames)` line, and the index's
/// `DataSet` count, which must agree.
fn frames_written(stdout: &str, pvd: &std::path::Path) -> usize {
    let listed = std::fs::read_to_string(pvd)
        .unwrap()
        .matches("<DataSet")
        .count();
    let said = stdout
        .lines()
        .find_map(|l| l.strip_prefix(&format!("wrote {} (", pvd.display())))
        .and_then(|r| r.strip_suffix(" frames)"))
        .unwrap_or_else(|| panic!("no series line in {stdout}"));
    assert_eq!(said.parse::<usize>().unwrap(), listed, "{stdout}");
    listed
}

#[test]
fn a_series_writes_the_frames_its_check_counts() {
    // A frame every T/dt ticks, rounded: at 60 Hz T = 0.025 s is 1.5 ticks, a frame
    // every second tick. Over 1 s (60 ticks): the start and 30 more. Over 0.35 s (21
    // ticks): the start, 10, and the end. The check before the run counts by the same
    // rule; it counted 42 where 47 were written when frames were due by elapsed time,
    // so that a run it let through could stop at its end and lose its --export.
    for (seconds, frames) in [("1", 31), ("0.35", 12)] {
        let out = temp(&format!("counted-{seconds}.pvd"));
        let run = succeed(
            server()
                .args(["run", "--seconds", seconds, "--export-every", "0.025"])
                .arg(&out),
        );
        let stdout = String::from_utf8_lossy(&run.stdout);
        assert_eq!(frames_written(&stdout, &out), frames, "{seconds} s");
    }
    // One tetrahedron at 1000 Hz, T = 1.2 ticks: a frame every tick, 110,001 over
    // 110 s, past the bound, refused at once (elapsed time counted 91,668 and let it
    // run).
    let dir = temp("bound");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("m.msh"), ONE_TET_MSH).unwrap();
    let scene = dir.join("tet.toml");
    std::fs::write(&scene, one_tet_scene("tet", "m.msh")).unwrap();
    let e = fail(
        server()
            .args(["run", "--seconds", "110", "--export-every", "0.0012"])
            .arg(dir.join("s.pvd"))
            .arg("--scene")
            .arg(&scene),
    );
    assert!(
        e.contains("110001 frames over 110 s (one every 1 ticks)"),
        "{e}"
    );
}

#[test]
fn a_series_whose_frames_would_write_over_an_input_or_the_export_is_refused() {
    let dir = temp("frames");
    std::fs::create_dir_all(&dir).unwrap();
    let traj = dir.join("ser_000001.vtu");
    let keyframes = "0, left, 0, 0, 0.2, 0, 0, 1\n";
    std::fs::write(&traj, keyframes).unwrap();
    let e = fail(
        server()
            .args(["run", "--seconds", "0.1", "--export-every", "0.05"])
            .arg(dir.join("ser.pvd"))
            .arg("--trajectory")
            .arg(&traj),
    );
    assert!(
        e.contains("trajectory file") && e.contains("ser_000001.vtu"),
        "{e}"
    );
    assert_eq!(std::fs::read_to_string(&traj).unwrap(), keyframes);
    // The single export named as the series' second frame would be written over by
    // it, or write over it: refused as well; a name outside the series is not.
    let e = fail(
        server()
            .args(["run", "--seconds", "0.1", "--export-every", "0.05"])
            .arg(dir.join("c2.pvd"))
            .arg("--export")
            .arg(dir.join("c2_000001.vtu")),
    );
    assert!(e.contains("--export") && e.contains("c2_000001.vtu"), "{e}");
    assert!(!dir.join("c2.pvd").exists());
    succeed(
        server()
            .args(["run", "--seconds", "0.1", "--export-every", "0.05"])
            .arg(dir.join("c3.pvd"))
            .arg("--export")
            .arg(dir.join("c3_00001.vtu")),
    );
}

#[test]
fn an_export_over_a_directory_is_refused_before_the_run() {
    let dir = temp("over-dir");
    let target = dir.join("d.vtu");
    std::fs::create_dir_all(&target).unwrap();
    let out = server()
        .args(["run", "--seconds", "0.5", "--export"])
        .arg(&target)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("it is a directory, not a regular file"), "{e}");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(!stdout.contains("ran "), "refused after running: {stdout}");
    // So is a series one of whose later frames is a directory: no frame written.
    std::fs::create_dir_all(dir.join("s_000003.vtu")).unwrap();
    let e = fail(
        server()
            .args(["run", "--seconds", "0.5", "--export-every", "0.1"])
            .arg(dir.join("s.pvd")),
    );
    assert!(e.contains("s_000003.vtu: it is a directory"), "{e}");
    assert!(!dir.join("s_000000.vtu").exists() && !dir.join("s.pvd").exists());
}

#[test]
fn a_static_solve_that_diverges_fails_and_exports_nothing() {
    // E = 1 Pa, 100 t/m³, a thousand times gravity: the linear static answer puts the
    // liver about 10⁶ m away, beyond the ±100 m a mesh must lie in. A time-stepped
    // run stops there; the static solve did not, and wrote it out.
    let dir = temp("static-diverged");
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("soft.toml");
    std::fs::write(
        &scene,
        "name = \"soft\"\ngravity = [1000.0, -1000.0, 1000.0]\n[mesh]\n\
         file = \"builtin:liver.msh\"\nscale = 0.05\n[material]\nmodel = \"linear\"\n\
         young_modulus = 1.0\npoisson_ratio = 0.45\ndensity = 1e5\n[fixed]\n\
         nodes = [3, 39, 64]\n",
    )
    .unwrap();
    let out = dir.join("soft.vtu");
    let e = fail(
        server()
            .args(["run", "--static", "--scene"])
            .arg(&scene)
            .arg("--export")
            .arg(&out),
    );
    assert!(e.contains("static solve") && e.contains("diverged"), "{e}");
    assert!(!out.exists());
}

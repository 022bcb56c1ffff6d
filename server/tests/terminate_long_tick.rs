//! SIGTERM to a real `laparo-server` while a session runs ticks as long as a scene may
//! make them: the process ends, and the session's recording is finished.

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use laparo_server::recording::Recording;

mod common;
use common::process::{Server, connect, create_recorded_session, free_port};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigterm_ends_a_server_whose_session_runs_the_longest_ticks_a_scene_may_ask() {
    let dir = tempfile::tempdir().unwrap();
    let scenes = dir.path().join("scenes");
    let recordings = dir.path().join("recordings");
    std::fs::create_dir(&scenes).unwrap();
    std::fs::write(
        scenes.join("liver-5k.msh"),
        include_str!("../meshes/liver-5k.msh"),
    )
    .unwrap();
    // liver-5k (1408 vertices) asking for a residual it cannot reach, at the most CG
    // iterations its tick may do (71 022): ticks of seconds.
    std::fs::write(
        scenes.join("long.toml"),
        "name = \"long\"\ngravity = [0.0, -9.81, 0.0]\n[mesh]\nfile = \"liver-5k.msh\"\n\
         scale = 0.03\ncenter = true\n[material]\nyoung_modulus = 3000.0\n\
         poisson_ratio = 0.3\ndensity = 1000.0\n[fixed]\nnodes = [3, 39, 64]\n\
         [mechanics]\ncg_tolerance = 1e-12\ncg_max_iterations = 71000\n",
    )
    .unwrap();
    let port = free_port();
    let child = Command::new(env!("CARGO_BIN_EXE_laparo-server"))
        .args(["--listen", &format!("127.0.0.1:{port}")])
        .arg("--scene-dir")
        .arg(&scenes)
        .arg("--recordings")
        .arg(&recordings)
        .env("RUST_LOG", "warn")
        .stdout(Stdio::null())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let mut server = Server(child);
    let (_, file) = create_recorded_session(connect(port).await, "long", &recordings).await;

    let term = Command::new("kill")
        .args(["-TERM", &server.0.id().to_string()])
        .status()
        .unwrap();
    assert!(term.success());
    // A bound on the wait, so that a hang fails the test instead of stalling it.
    let deadline = Instant::now() + Duration::from_secs(30);
    let status = loop {
        if let Some(status) = server.0.try_wait().unwrap() {
            break status;
        }
        assert!(Instant::now() < deadline, "SIGTERM did not end the server");
        tokio::time::sleep(Duration::from_millis(20)).await;
    };
    assert!(status.success(), "{status:?}");
    let recording = Recording::open(&file).unwrap();
    assert!(recording.is_complete(), "the recording was finished");
}

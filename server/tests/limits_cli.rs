//! `laparo-server` given out-of-range durations, a host that is not a name, an
//! address without a port, or a scene whose mesh would block: a usage error or a
//! clear failure, never a panic or a hang.

use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

fn server() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_laparo-server"));
    c.stdout(Stdio::piped()).stderr(Stdio::piped());
    c
}

/// Waits for `child` at most 30 s (killing it then, which fails the test).
fn finish(mut child: Child) -> Output {
    let deadline = Instant::now() + Duration::from_secs(30);
    while child.try_wait().unwrap().is_none() {
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!(
                "laparo-server did not finish: {:?}",
                child.wait_with_output()
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

#[test]
fn an_idle_timeout_out_of_range_is_a_usage_error_naming_the_option_and_range() {
    for bad in ["1e20", "1.85e19", "inf", "-1", "604801"] {
        let out = finish(
            server()
                .args(["--listen", "127.0.0.1:0", "--no-recording"])
                .arg(format!("--idle-timeout={bad}"))
                .spawn()
                .unwrap(),
        );
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{bad}: {stderr}");
        assert!(
            stderr.contains("--idle-timeout") && stderr.contains("604800"),
            "{bad}: {stderr}"
        );
        assert!(!stderr.contains("panicked"), "{bad}: {stderr}");
    }
}

#[test]
fn a_station_timeout_out_of_range_is_a_usage_error_naming_the_option_and_range() {
    for bad in ["0", "0.4", "-1", "3601", "1e20", "inf", "NaN", "five"] {
        let out = finish(
            server()
                .args(["--listen", "127.0.0.1:0", "--no-recording"])
                .arg(format!("--station-timeout={bad}"))
                .spawn()
                .unwrap(),
        );
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{bad}: {stderr}");
        assert!(stderr.contains("--station-timeout"), "{bad}: {stderr}");
        assert!(!stderr.contains("panicked"), "{bad}: {stderr}");
    }
}

#[test]
fn an_allowed_host_that_is_not_a_name_is_a_usage_error_naming_the_option() {
    for bad in ["laparo.lan:50051", "http://laparo.lan", "*", "[::1]", ""] {
        let out = finish(
            server()
                .args(["--listen", "127.0.0.1:0", "--no-recording"])
                .arg(format!("--allowed-host={bad}"))
                .spawn()
                .unwrap(),
        );
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{bad}: {stderr}");
        assert!(stderr.contains("--allowed-host"), "{bad}: {stderr}");
        assert!(!stderr.contains("panicked"), "{bad}: {stderr}");
    }
}

#[test]
fn a_listen_address_without_a_port_is_a_usage_error_naming_the_forms() {
    for bad in ["localhost", "127.0.0.1", "127.0.0.1:70000", ":50051"] {
        let out = finish(
            server()
                .args(["--no-recording", "--listen", bad])
                .spawn()
                .unwrap(),
        );
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{bad}: {stderr}");
        assert!(
            stderr.contains("--listen") && stderr.contains("localhost:50051"),
            "{bad}: {stderr}"
        );
    }
}

#[test]
fn a_headless_run_on_a_fifo_mesh_fails_instead_of_blocking() {
    let dir = tempfile::tempdir().unwrap();
    let pipe = dir.path().join("pipe.msh");
    assert!(
        Command::new("mkfifo")
            .arg(&pipe)
            .status()
            .unwrap()
            .success()
    );
    let scene = dir.path().join("fifo.toml");
    std::fs::write(
        &scene,
        "name = \"fifo\"\n[mesh]\nfile = \"pipe.msh\"\n[material]\nyoung_modulus = 3000.0\n\
         poisson_ratio = 0.3\ndensity = 1000.0\n",
    )
    .unwrap();
    let out = finish(
        server()
            .args(["run", "--seconds", "0.1", "--scene"])
            .arg(&scene)
            .spawn()
            .unwrap(),
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("FIFO"), "{stderr}");
}

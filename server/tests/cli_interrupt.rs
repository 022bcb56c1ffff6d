//! `laparo-server run` stopped by SIGINT (Ctrl-C) while it writes a time series:
//! it ends with an error naming the tick, leaves no part file, writes no
//! `--export`, and leaves an index that lists exactly the frames on disk.

#![cfg(unix)]

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("laparo-sigint-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The frame files the index at `pvd` lists, in its folder.
fn listed(pvd: &Path) -> Vec<PathBuf> {
    let text = std::fs::read_to_string(pvd).unwrap();
    assert!(text.trim_end().ends_with("</VTKFile>"), "{text}");
    text.split("file=\"")
        .skip(1)
        .map(|rest| pvd.with_file_name(&rest[..rest.find('"').unwrap()]))
        .collect()
}

#[test]
fn sigint_during_a_series_ends_the_run_cleanly() {
    // Signalled at once, and some frames later: inside a frame's write or between.
    for (k, delay_ms) in [0u64, 7, 40].into_iter().enumerate() {
        let dir = temp(&k.to_string());
        let (pvd, export) = (dir.join("s.pvd"), dir.join("final.vtu"));
        let mut child = Command::new(env!("CARGO_BIN_EXE_laparo-server"))
            .args(["run", "--seconds", "1000", "--export-every", "0.05"])
            .arg(&pvd)
            .arg("--export")
            .arg(&export)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let start = Instant::now();
        while !pvd.exists() {
            assert!(
                start.elapsed() < Duration::from_secs(60),
                "no series after 60 s"
            );
            assert!(child.try_wait().unwrap().is_none(), "the run ended early");
            std::thread::sleep(Duration::from_millis(2));
        }
        std::thread::sleep(Duration::from_millis(delay_ms));
        // SAFETY: kill(2) on the child's pid, which has not been waited for and so
        // cannot have been reused.
        let sent = unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGINT) };
        assert_eq!(sent, 0, "{}", std::io::Error::last_os_error());
        let out = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        assert!(
            stderr.contains("interrupted at tick") && stderr.contains("--export not written"),
            "{stderr}"
        );
        assert!(!export.exists());
        let files: Vec<PathBuf> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        assert!(
            files
                .iter()
                .all(|f| f.extension().is_none_or(|e| e != "part")),
            "{files:?}"
        );
        // The index lists every frame on disk and nothing else, and says how many.
        let mut frames = listed(&pvd);
        frames.sort();
        let mut on_disk: Vec<PathBuf> = files
            .into_iter()
            .filter(|f| f.extension().is_some_and(|e| e == "vtu"))
            .collect();
        on_disk.sort();
        assert_eq!(frames, on_disk);
        assert!(
            stderr.contains(&format!("holds the {} frames", frames.len())),
            "{stderr}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

//! `laparo demo`, the README's main job, end to end: a server in the process, a
//! station pressing the liver through its force loop, a summary.

use std::process::Command;

#[test]
fn the_demo_presses_the_liver_and_reports() {
    let dir = std::env::temp_dir().join(format!("laparo-demo-{}", std::process::id()));
    let out = Command::new(env!("CARGO_BIN_EXE_laparo"))
        .args(["demo", "--seconds", "3.5", "--recordings"])
        .arg(&dir)
        .output()
        .expect("laparo runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // The tip press reaches the liver within 3.5 s: a force was felt and reported.
    let max_force: f64 = stdout
        .lines()
        .find_map(|l| l.trim().strip_prefix("max |force|"))
        .and_then(|v| v.trim().trim_end_matches('N').trim().parse().ok())
        .unwrap_or_else(|| panic!("no max |force| line in\n{stdout}"));
    assert!(max_force > 0.05, "max force {max_force} N\n{stdout}");
    assert!(stdout.contains("CONTACT_BEGAN"), "{stdout}");
    assert!(stdout.contains("station errors       none"), "{stdout}");
    // The session was recorded where asked, and the summary says where.
    let files: Vec<_> = std::fs::read_dir(&dir).unwrap().flatten().collect();
    assert_eq!(files.len(), 1, "{files:?}");
    let name = files[0].file_name().to_string_lossy().to_string();
    assert!(
        name.ends_with(".mcap") && stdout.contains(&name),
        "{name}\n{stdout}"
    );
    assert!(files[0].metadata().unwrap().len() > 10_000);
    // The recording reads back: replay's summary and the list.
    let laparo = |args: &[&std::ffi::OsStr]| {
        let out = Command::new(env!("CARGO_BIN_EXE_laparo"))
            .args(args)
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout).to_string();
        assert!(
            out.status.success(),
            "{text}{}",
            String::from_utf8_lossy(&out.stderr)
        );
        text
    };
    let path = files[0].path();
    let replay = laparo(&["replay".as_ref(), path.as_os_str()]);
    let ticks: u64 = replay
        .lines()
        .find_map(|l| l.trim().strip_prefix("ticks"))
        .and_then(|v| v.trim().parse().ok())
        .unwrap_or_else(|| panic!("{replay}"));
    assert!(ticks > 100, "{replay}");
    assert!(replay.contains("left: path"), "{replay}");
    let list = laparo(&[
        "recordings".as_ref(),
        "list".as_ref(),
        "--dir".as_ref(),
        dir.as_os_str(),
    ]);
    assert!(list.contains(&name) && list.contains("default"), "{list}");
    // Cut short as by a killed server, recovered, read back.
    let bytes = std::fs::read(&path).unwrap();
    let cut = dir.join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() * 3 / 4]).unwrap();
    let recovered = dir.join("recovered.mcap");
    laparo(&[
        "recordings".as_ref(),
        "recover".as_ref(),
        cut.as_os_str(),
        "--out".as_ref(),
        recovered.as_os_str(),
    ]);
    let again = laparo(&["replay".as_ref(), recovered.as_os_str()]);
    assert!(again.contains("ticks"), "{again}");
    let _ = std::fs::remove_dir_all(&dir);
}

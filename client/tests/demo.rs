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
    let _ = std::fs::remove_dir_all(&dir);
}

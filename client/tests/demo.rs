//! `laparo demo`, the README's main job, end to end: a server in the process, a
//! station pressing the liver through its force loop, a summary.

use std::process::Command;

#[test]
fn the_demo_presses_the_liver_and_reports() {
    let out = Command::new(env!("CARGO_BIN_EXE_laparo"))
        .args(["demo", "--seconds", "3.5"])
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
}

//! `laparo demo`, the README's main job, end to end: a server in the process, a
//! station pressing the liver through its force loop, a summary.

use std::process::Command;

use laparo_client::plot::{COLORS, Picture};

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
    // It says where to watch: the console of the server it runs.
    assert!(
        stdout
            .lines()
            .any(|l| l.starts_with("demo: console http://127.0.0.1:") && l.contains("/ ")),
        "{stdout}"
    );
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
    // The forces plotted from the same recording.
    let png = dir.join("forces.png");
    let plotted = laparo(&[
        "replay".as_ref(),
        path.as_os_str(),
        "--plot".as_ref(),
        png.as_os_str(),
        "--plot-size".as_ref(),
        "900x480".as_ref(),
    ]);
    let line = plotted
        .lines()
        .find_map(|l| l.trim().strip_prefix("plot"))
        .unwrap_or_else(|| panic!("no plot line in\n{plotted}"));
    assert!(
        line.contains("forces.png") && line.contains("left"),
        "{line}"
    );
    // It reads `|force| 0.000–F N`: F is above the largest force, with room for
    // the legend.
    let top: f64 = line
        .split_once("–")
        .and_then(|(_, rest)| rest.split_once(' '))
        .and_then(|(f, _)| f.parse().ok())
        .unwrap_or_else(|| panic!("{line}"));
    let max_replayed: f64 = plotted
        .lines()
        .find_map(|l| {
            l.split_once("force max ")?
                .1
                .split_once(' ')?
                .0
                .parse()
                .ok()
        })
        .unwrap_or_else(|| panic!("{plotted}"));
    assert!(
        top > 1.1 * max_replayed && top < 2.0 * max_replayed,
        "{line}"
    );
    let picture = Picture::read(&png).unwrap();
    assert_eq!((picture.width, picture.height), (900, 480));
    // The left instrument's curve across the chart (above the contact lanes), and
    // its contact lane filled: the demo pressed the liver.
    let colour = |(r, g, b): (u8, u8, u8)| [r, g, b];
    let curve = picture
        .pixels()
        .filter(|&(_, y, p)| y < 360 && p == colour(COLORS[0]))
        .count();
    assert!(curve > 450, "{curve} pixels of the force curve");
    let lane = picture
        .pixels()
        .filter(|&(_, y, p)| y >= 380 && p == colour(COLORS[0]))
        .count();
    assert!(lane > 100, "{lane} pixels of the contact lane");
    // A path that cannot be written: a clear error, exit status 1, before the
    // summary is printed (it was printed whole, then the plot refused).
    let bad = dir.join("no-such-dir").join("forces.png");
    let folder = dir.join("a-folder.png");
    std::fs::create_dir_all(&folder).unwrap();
    for (target, why) in [
        (&bad, "No such file or directory"),
        (&folder, "it is a folder"),
        (&dir.join("forces.svg"), "must end in .png"),
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_laparo"))
            .args(["replay".as_ref(), path.as_os_str(), "--plot".as_ref()])
            .arg(target)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        assert!(
            stderr.contains(&format!("cannot plot to {}", target.display()))
                && stderr.contains(why),
            "{stderr}"
        );
        assert!(out.stdout.is_empty(), "printed before refusing: {out:?}");
    }
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
    let said = laparo(&[
        "recordings".as_ref(),
        "recover".as_ref(),
        cut.as_os_str(),
        "--out".as_ref(),
        recovered.as_os_str(),
    ]);
    assert!(
        said.contains("after the last complete chunk left out (what was being written)"),
        "{said}"
    );
    let again = laparo(&["replay".as_ref(), recovered.as_os_str()]);
    assert!(again.contains("ticks"), "{again}");
    // Recovering over another recording is refused unless asked, and the file is
    // left as it was.
    let kept = std::fs::read(&path).unwrap();
    let over = [
        "recordings".as_ref(),
        "recover".as_ref(),
        cut.as_os_str(),
        "--out".as_ref(),
        path.as_os_str(),
    ];
    let stderr = fails(&over);
    assert!(
        stderr.contains("it exists and is not the file recovered"),
        "{stderr}"
    );
    assert_eq!(std::fs::read(&path).unwrap(), kept);
    laparo(&[&over[..], &["--replace".as_ref()]].concat());
    assert_eq!(
        std::fs::read(&path).unwrap(),
        std::fs::read(&recovered).unwrap()
    );
    // A scene given to resim that does not parse is named by its own file and line,
    // not by the recorded scene's name.
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "name = \"x\"\n[mesh\n").unwrap();
    let stderr = fails(&[
        "resim".as_ref(),
        path.as_os_str(),
        "--scene".as_ref(),
        bad.as_os_str(),
    ]);
    assert!(
        stderr.contains(&format!("{}:2:", bad.display())) && !stderr.contains("default:"),
        "{stderr}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_demo_that_cannot_record_fails_and_names_no_recording() {
    let dir = std::env::temp_dir().join(format!("laparo-demo-norec-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("a-file");
    std::fs::write(&file, b"not a folder").unwrap();
    // A file as the folder, or a folder inside a file: refused before the demo
    // starts, saying why.
    for (recordings, why) in [
        (file.clone(), "is not a directory"),
        (
            file.join("sub"),
            "cannot be made or reached: Not a directory",
        ),
    ] {
        let stderr = fails(&[
            "demo".as_ref(),
            "--seconds".as_ref(),
            "0.5".as_ref(),
            "--recordings".as_ref(),
            recordings.as_os_str(),
        ]);
        assert!(stderr.contains(why), "{stderr}");
        assert!(stderr.contains("cannot be recorded in it"), "{stderr}");
    }
    // A folder whose path leaves no room for a file name (`ENAMETOOLONG` past 4,095
    // bytes) passes that check: the demo runs, the recorder fails, and the run ends
    // saying the session was not recorded, naming the cause.
    let mut long = dir.clone();
    while long.as_os_str().len() < 3800 {
        long.push("d".repeat(200));
    }
    long.push("d".repeat(4080 - long.as_os_str().len() - 1));
    std::fs::create_dir_all(&long).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_laparo"))
        .args(["demo", "--seconds", "0.5", "--recordings"])
        .arg(&long)
        .output()
        .expect("laparo runs");
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert_eq!(out.status.code(), Some(1), "{stdout}\n{stderr}");
    assert!(stdout.contains("recording            none:"), "{stdout}");
    assert!(stdout.contains("File name too long"), "{stdout}");
    assert!(!stdout.contains("compression stream"), "{stdout}");
    assert!(stderr.contains("the session was not recorded"), "{stderr}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Runs `laparo` with `args`, which must fail with exit status 1; its stderr.
fn fails(args: &[&std::ffi::OsStr]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_laparo"))
        .args(args)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(1), "{args:?}: {stderr}");
    stderr
}

//! `laparo resim FILE`: the recorded poses through the recorded (or another) scene,
//! and the largest deviation from the recorded surfaces and forces.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use clap::Args;
use laparo_server::engine::scene::{MAX_SCENE_BYTES, read_bounded};
use laparo_server::recording::{ResimError, TOPIC_SURFACE, resimulate_as};

use super::BoxError;
use super::out::{self, say};
use super::replay::open_recording;

/// `laparo resim`.
#[derive(Args, Debug, Clone)]
pub struct ResimArgs {
    /// A session recording (.mcap).
    #[arg(value_name = "FILE")]
    pub file: PathBuf,
    /// Folder the scene's mesh path resolves against [default: the one the server
    /// recorded].
    #[arg(long, value_name = "DIR")]
    pub scene_dir: Option<PathBuf>,
    /// Run the recorded hands on this scene instead (same mesh; another material or
    /// force model): the deviation then measures the change.
    #[arg(long, value_name = "FILE.toml")]
    pub scene: Option<PathBuf>,
}

/// Re-simulates the recording and prints the deviations.
pub fn run(args: ResimArgs) -> Result<(), BoxError> {
    let recording = open_recording(&args.file)?;
    let mut meta = recording.meta().clone();
    if let Some(scene) = &args.scene {
        let bytes = read_bounded(scene, None, MAX_SCENE_BYTES)
            .map_err(|e| format!("cannot read {}: {e}", scene.display()))?;
        meta.scene_toml = String::from_utf8(bytes)
            .map_err(|e| format!("{} is not UTF-8 text: {e}", scene.display()))?;
        // The scene's errors name this file, not the recorded scene.
        meta.scene = scene.display().to_string();
        // A bare file name's folder is the working one (its parent is empty).
        meta.scene_dir = scene
            .parent()
            .map(|p| {
                if p.as_os_str().is_empty() {
                    Path::new(".")
                } else {
                    p
                }
            })
            .map(Path::to_path_buf);
    }
    let total = recording.message_counts().get(TOPIC_SURFACE).copied();
    // A progress line once a second on stderr, for long recordings.
    let mut next_line = Instant::now() + Duration::from_secs(1);
    let mut shown = false;
    let r = resimulate_as(&recording, &meta, args.scene_dir.as_deref(), |tick| {
        if Instant::now() >= next_line {
            // Not `eprint!`: it panics when stderr cannot be written.
            let _ = write!(
                std::io::stderr(),
                "\r  tick {tick} of {}",
                total.unwrap_or(0)
            );
            next_line += Duration::from_secs(1);
            shown = true;
        }
    })
    .map_err(|e| -> BoxError {
        match (&args.scene, e) {
            // The scene given in place of the recorded one is what does not build.
            (Some(file), ResimError::Scene(e)) => {
                format!("{} does not build: {e}", file.display()).into()
            }
            (_, e) => e.into(),
        }
    })?;
    if shown {
        out::tell(format_args!(""));
    }
    say!(
        "{}: re-simulated {} recorded ticks ({:.3} s simulated) in {:.2} s wall ({:.1}× real time)",
        args.file.display(),
        r.ticks_compared,
        r.sim_time_s,
        r.elapsed_s,
        r.sim_time_s / r.elapsed_s.max(1e-9)
    );
    match r.worst_surface_tick {
        Some(t) => say!(
            "  largest surface deviation {:.3e} m (tick {t})",
            r.max_surface_deviation_m
        ),
        None => say!("  largest surface deviation 0 m"),
    }
    say!(
        "  largest force deviation   {:.3e} N",
        r.max_force_deviation_n
    );
    say!("  contact state mismatches  {}", r.contact_mismatches);
    if let Some(t) = r.first_missing_tick {
        say!(
            "  {} ticks are missing from the recording (the recorder fell behind), from tick {t}: deviations after it are expected",
            r.missing_ticks
        );
    }
    say!(
        "  {}",
        if r.ticks_compared == 0 {
            "nothing compared: the recording holds no tick"
        } else if r.is_exact() {
            "identical to the recording"
        } else {
            "differs from the recording"
        }
    );
    Ok(())
}

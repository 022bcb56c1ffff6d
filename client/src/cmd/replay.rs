//! `laparo replay FILE`: a recording's summary (and, with `--plot`, its forces over
//! time as a PNG); with `--server`, the server plays one of its recordings back and
//! this watches it as `laparo observe` watches a session.

use std::path::{Path, PathBuf};

use clap::Args;
use laparo_proto::text::printable;
use laparo_server::recording::{Recording, summarize};

use super::args::{RemoteArgs, offset, plot_size, speed};
use super::observe::{print_report, print_watch_summary};
use super::out::{self, say};
use super::{BoxError, ctrl_c};
use crate::connect::ConnectConfig;
use crate::observe::{ObserveConfig, run_observe};
use crate::plot::{check_target, draw, force_series};
use crate::proto::v1::{ReplayMode, ReplayRequest};

/// `laparo replay`.
#[derive(Args, Debug, Clone)]
pub struct ReplayArgs {
    /// A session recording (.mcap); with `--server`, the name of one of the server's
    /// recordings (as `laparo recordings list --server` shows it).
    #[arg(value_name = "FILE")]
    pub file: PathBuf,
    /// Also plot |force| per instrument over simulated time, contact intervals
    /// shaded, to this PNG file.
    #[arg(long, value_name = "OUT.png", conflicts_with = "server")]
    pub plot: Option<PathBuf>,
    /// Size of the plot, pixels.
    #[arg(long, value_name = "WxH", value_parser = plot_size, default_value = "1200x600", requires = "plot")]
    pub plot_size: (u32, u32),
    #[command(flatten)]
    pub remote: RemoteArgs,
    /// Playback speed factor: 2 plays twice as fast (the server takes 0.01 to 100).
    #[arg(long, value_name = "S", requires = "server", value_parser = speed)]
    pub speed: Option<f64>,
    /// Where to start, s of simulated time from the start of the recording.
    #[arg(long, value_name = "T", requires = "server", value_parser = offset)]
    pub from: Option<f64>,
    /// Have the server re-run the recorded poses through the recorded scene and
    /// send that, instead of the recorded frames.
    #[arg(long, requires = "server")]
    pub resimulate: bool,
}

/// Summarises the recording here, or watches the server play it back.
pub async fn run(args: ReplayArgs) -> Result<(), BoxError> {
    if let Some(connect) = args.remote.connect_config() {
        return watch(connect, &args).await;
    }
    if let Some(out) = &args.plot {
        check_target(out)?;
    }
    let recording = open_recording(&args.file)?;
    let s = summarize(&recording)?;
    let meta = recording.meta();
    say!(
        "{}",
        heading(
            &args.file,
            &meta.session_id,
            &meta.scene,
            &meta.format_version
        )
    );
    say!("  duration             {:.3} s simulated", s.duration_s);
    say!("  ticks                {}", s.ticks);
    say!("  poses received       {}", s.poses);
    for (name, i) in &s.instruments {
        say!(
            "  {}: path {:.1} mm, in contact {:.2} s, force max {:.3} N mean {:.3} N (in contact {:.3} N), largest jump {:.3} N",
            printable(name),
            i.path_length_m * 1e3,
            i.time_in_contact_s,
            i.max_force_n,
            i.mean_force_n,
            i.mean_contact_force_n,
            i.max_force_jump_n
        );
    }
    for (kind, n) in &s.events {
        say!("  event {:<28} {n}", printable(kind));
    }
    if let Some(out) = &args.plot {
        let states = recording.instrument_states()?;
        let series = force_series(states.iter().map(|s| &s.message));
        let title = format!(
            "session {} of scene {}: force on each instrument",
            meta.session_id, meta.scene
        );
        let r = draw(&series, &title, out, args.plot_size)?;
        let plotted: Vec<&str> = series.iter().map(|s| s.instrument.as_str()).collect();
        let left_out: Vec<&str> = s
            .instruments
            .keys()
            .map(String::as_str)
            .filter(|name| !plotted.contains(name))
            .collect();
        say!(
            "  plot                 {} ({}x{} px): axes |force| {:.3}–{:.3} N and {:.3}–{:.3} s simulated, {}{}",
            out.display(),
            args.plot_size.0,
            args.plot_size.1,
            r.force_n.0,
            r.force_n.1,
            r.time_s.0,
            r.time_s.1,
            if plotted.is_empty() {
                "no instrument".to_string()
            } else {
                printable(&plotted.join(", ")).into_owned()
            },
            if left_out.is_empty() {
                String::new()
            } else {
                format!(
                    " (left out, never posed: {})",
                    printable(&left_out.join(", "))
                )
            }
        );
    }
    Ok(())
}

/// The first line of a recording's summary: its file, session, scene and format,
/// what comes from the file escaped ([`printable`]) so that a control character in a
/// name cannot act on the terminal.
fn heading(file: &Path, session: &str, scene: &str, format_version: &str) -> String {
    format!(
        "{}: session {} of scene `{}`, format {}",
        printable(&file.display().to_string()),
        printable(session),
        printable(scene),
        printable(format_version)
    )
}

/// Opens a recording; one cut short (a killed server, a session still recording)
/// is read up to its last complete chunk, with a note saying so.
pub(crate) fn open_recording(path: &Path) -> Result<Recording, BoxError> {
    let recording = Recording::open_unfinished(path)?;
    if !recording.is_complete() {
        out::tell(format_args!(
            "note: {} ends without its summary (a killed server, or still being recorded); \
             read up to its last complete chunk. `laparo recordings recover` rewrites it \
             into a complete file.",
            path.display(),
        ));
    }
    Ok(recording)
}

/// `laparo replay FILE --server URL`: the server's recording FILE, played back.
async fn watch(connect: ConnectConfig, args: &ReplayArgs) -> Result<(), BoxError> {
    let file = args
        .file
        .to_str()
        .ok_or_else(|| format!("{}: not a UTF-8 file name", args.file.display()))?
        .to_string();
    let request = ReplayRequest {
        file: file.clone(),
        speed: args.speed,
        start_offset_s: args.from,
        mode: if args.resimulate {
            ReplayMode::Resimulate
        } else {
            ReplayMode::Recorded
        } as i32,
    };
    let config = ObserveConfig {
        connect,
        stop: Some(ctrl_c()),
        ..ObserveConfig::replay(args.remote.server.clone().unwrap_or_default(), request)
    };
    let what = format!(
        "replaying {file} at {}x from {} s",
        args.speed.unwrap_or(1.0),
        args.from.unwrap_or(0.0)
    );
    let summary = run_observe(config, print_report(what)).await?;
    print_watch_summary(&summary, "the recording ended");
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_heading_escapes_control_characters_of_the_file() {
        let h = heading(
            Path::new("r\u{1b}[31m.mcap"),
            "s\u{1b}]0;pwned\u{7}",
            "scene\0\u{202e}",
            "1\n",
        );
        assert!(
            !h.chars().any(|c| c.is_control() || c == '\u{202e}'),
            "{h:?}"
        );
        assert!(
            h.contains(r"session s\u{1b}]0;pwned\u{7} of scene `scene\u{0}\u{202e}`"),
            "{h}"
        );
    }
}

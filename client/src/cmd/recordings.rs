//! `laparo recordings list|recover`: the recordings of a directory or a server, one
//! markdown table row each; a truncated recording rewritten into a complete one.

use std::path::{Path, PathBuf};

use clap::Subcommand;
use laparo_proto::text::printable;
use laparo_server::recording::recover::lost;
use laparo_server::recording::{Existing, FileState, list, recover};

use super::BoxError;
use super::args::RemoteArgs;
use super::out::say;
use crate::connect::{ConnectConfig, connect, describe_status, unary};
use crate::proto::v1::{ListRecordingsRequest, RecordingInfo, RecordingState};

/// `laparo recordings …`.
#[derive(Subcommand, Debug, Clone)]
pub enum RecordingsCommand {
    /// List the recordings of a directory, or of a server with `--server`: session,
    /// scene, start, duration, size, and whether each is complete or still being
    /// recorded.
    List {
        /// The recordings directory.
        #[arg(
            long,
            value_name = "DIR",
            default_value = "recordings",
            conflicts_with = "server"
        )]
        dir: PathBuf,
        #[command(flatten)]
        remote: RemoteArgs,
    },
    /// Rewrite a truncated recording (a server killed mid-session) into a valid,
    /// indexed one, keeping every complete chunk.
    Recover {
        /// The truncated recording.
        #[arg(value_name = "FILE")]
        file: PathBuf,
        /// Where to write the recovered file [default: over FILE].
        #[arg(long, value_name = "OUT")]
        out: Option<PathBuf>,
        /// Replace OUT if it is another file that exists (refused otherwise, so
        /// that no other recording is lost by a mistyped name).
        #[arg(long, requires = "out")]
        replace: bool,
    },
}

/// Runs `list` or `recover`.
pub async fn run(command: RecordingsCommand) -> Result<(), BoxError> {
    match command {
        RecordingsCommand::List { dir, remote } => match remote.connect_config() {
            Some(server) => list_server(&server).await,
            None => list_dir(&dir),
        },
        RecordingsCommand::Recover { file, out, replace } => {
            let out = out.unwrap_or_else(|| file.clone());
            let existing = match replace {
                true => Existing::Replace,
                false => Existing::Refuse,
            };
            let r = recover(&file, &out, existing)?;
            let lost = lost(&r);
            say!(
                "{} → {}: {}, {} kept ({} bytes); {}",
                file.display(),
                out.display(),
                counted(r.chunks, "chunk", "chunks"),
                counted(r.messages, "message", "messages"),
                r.bytes_kept,
                if !lost.is_empty() {
                    format!("left out: {lost}")
                } else if r.was_complete {
                    "nothing left out (it had its footer already)".to_string()
                } else {
                    format!(
                        "{} bytes after the last complete chunk left out (what was being written)",
                        r.bytes_dropped
                    )
                }
            );
            for schema in &r.damaged_schemas {
                say!("  damaged {schema}");
            }
            match r.reframed_chunks {
                0 => {}
                1 => say!(
                    "  1 chunk whose length or opcode was damaged was framed by the file's \
                     chunk index and kept whole (its CRC matched)"
                ),
                n => say!(
                    "  {n} chunks whose length or opcode was damaged were framed by the file's \
                     chunk index and kept whole (their CRC matched)"
                ),
            }
            Ok(())
        }
    }
}

/// `n` of a thing, in the singular for one: "1 chunk", "7 chunks".
fn counted(n: u64, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

/// The table's header, printed once there is something to list.
fn header() {
    say!("| file | session | scene | start (unix s) | duration (s) | size (bytes) | state |");
    say!("|---|---|---|---|---|---|---|");
}

/// The rows of a server's recordings (`ListRecordings`), the header once it
/// answered.
async fn list_server(server: &ConnectConfig) -> Result<(), BoxError> {
    let connection = connect(server).await?;
    let listed = connection
        .recordings()
        .list_recordings(unary(ListRecordingsRequest {}))
        .await
        .map_err(|status| {
            format!(
                "listing the recordings of {}: {}",
                server.url,
                describe_status(&status)
            )
        })?
        .into_inner();
    header();
    let shown = listed.recordings.len();
    for r in listed.recordings {
        let start = r
            .start
            .map_or(0.0, |t| t.seconds as f64 + t.nanos as f64 * 1e-9);
        let state = server_state(&r);
        let row = row_text(
            &r.file,
            &r.session_id,
            &r.scene,
            start,
            r.duration_s,
            r.size_bytes,
            &state,
        );
        say!("{row}");
    }
    if listed.left_out > 0 {
        say!(
            "{} older recordings not listed (the server lists the newest {}); replay them by name",
            listed.left_out,
            shown
        );
    }
    Ok(())
}

/// How a recording of a server's listing ends, as the server says: its `state`, or
/// for a server from before `state` its `in_progress`.
fn server_state(r: &RecordingInfo) -> String {
    match RecordingState::try_from(r.state) {
        Ok(RecordingState::Complete) => "complete".into(),
        Ok(RecordingState::InProgress) => "in progress".into(),
        Ok(RecordingState::Unfinished) => "unfinished: no footer, its server stopped while \
            recording it (replay refuses it until `laparo recordings recover` completes it)"
            .into(),
        Ok(RecordingState::Failed) => format!(
            "failed: its recorder stopped while the session ran ({}); replay refuses it until \
             `laparo recordings recover` completes what was written",
            printable(&r.failure)
        ),
        Ok(RecordingState::Unspecified) if r.in_progress => "in progress".into(),
        Ok(RecordingState::Unspecified) => "complete".into(),
        Err(_) => format!("state {} (unknown to this client)", r.state),
    }
}

/// The rows of the recordings in `dir`, an unreadable one with why.
fn list_dir(dir: &Path) -> Result<(), BoxError> {
    let listed = list(dir, laparo_server::recording::lock::path_being_written)
        .map_err(|e| format!("{}: {e}", dir.display()))?;
    header();
    for l in listed {
        match &l.entry {
            Ok(e) => say!(
                "{}",
                row_text(
                    &l.file,
                    &e.session_id,
                    &e.scene,
                    e.start_unix_ns as f64 * 1e-9,
                    e.duration_s,
                    l.size_bytes,
                    match e.state {
                        FileState::Complete => "complete",
                        FileState::InProgress => "in progress",
                        FileState::Unfinished => {
                            "no footer: still being recorded, or cut short (`recordings recover` completes it)"
                        }
                    },
                )
            ),
            Err(e) => say!(
                "| {} | — | — | — | — | {} | {} |",
                printable(&l.file),
                l.size_bytes,
                printable(&e.to_string())
            ),
        }
    }
    Ok(())
}

/// One row of `laparo recordings list`, from a directory or a server alike, with
/// what comes from files (names) escaped ([`printable`]): a control character in a session or scene name reaches the
/// terminal as its escape.
fn row_text(
    file: &str,
    session: &str,
    scene: &str,
    start_unix_s: f64,
    duration_s: f64,
    size_bytes: u64,
    state: &str,
) -> String {
    let (file, session, scene) = (printable(file), printable(session), printable(scene));
    format!(
        "| {file} | {session} | {scene} | {start_unix_s:.0} | {duration_s:.2} | {size_bytes} | {} |",
        printable(state)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_server_listing_shows_the_state_the_server_gives() {
        let info = |state: RecordingState, in_progress| RecordingInfo {
            state: state as i32,
            in_progress,
            ..RecordingInfo::default()
        };
        // Cut short: not in progress, and not complete either.
        let unfinished = server_state(&info(RecordingState::Unfinished, false));
        assert!(unfinished.starts_with("unfinished") && unfinished.contains("recover"));
        // Its recorder failed: the server's reason is shown.
        let failed = server_state(&RecordingInfo {
            failure: "cannot write x.mcap: No space left on device (os error 28)".into(),
            ..info(RecordingState::Failed, false)
        });
        assert!(
            failed.starts_with("failed")
                && failed.contains("No space left")
                && failed.contains("recover"),
            "{failed}"
        );
        assert_eq!(
            server_state(&info(RecordingState::Complete, false)),
            "complete"
        );
        assert_eq!(
            server_state(&info(RecordingState::InProgress, true)),
            "in progress"
        );
        // A server from before `state`.
        assert_eq!(
            server_state(&info(RecordingState::Unspecified, true)),
            "in progress"
        );
        assert_eq!(
            server_state(&info(RecordingState::Unspecified, false)),
            "complete"
        );
        let unknown = RecordingInfo {
            state: 9,
            ..RecordingInfo::default()
        };
        assert!(server_state(&unknown).contains("state 9"));
    }

    #[test]
    fn a_row_escapes_control_characters_of_names() {
        let row = row_text(
            "a\u{1b}]0;x\u{7}.mcap",
            "s\u{1b}[2J",
            "sc\0ene\u{9b}",
            0.0,
            1.0,
            2,
            "complete",
        );
        assert!(!row.chars().any(|c| c.is_control()), "{row:?}");
        assert!(
            row.contains(r"s\u{1b}[2J") && row.contains(r"sc\u{0}ene\u{9b}"),
            "{row}"
        );
    }
}

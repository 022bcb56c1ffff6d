//! Standard output of the subcommands.
//!
//! `laparo … | head -1` closes the pipe after the first line. Rust ignores SIGPIPE,
//! so the next write fails with `BrokenPipe` (where `println!` would panic with
//! "failed printing to stdout"). Whoever reads has all it wanted: [`line()`] then ends
//! the process at once, with status 0 and nothing on stderr, as a Unix filter does.
//! Any other write failure (a full disk under a redirected output) ends it with
//! status 1 and says why on stderr.
//!
//! A command that owns something which must be closed in order — `laparo demo`
//! serves a recorded session in its own process — calls [`finish_when_closed`]
//! first: a closed pipe then only silences the rest of its output, and the command
//! runs to its end, so the session closes and its recording is finished.

use std::fmt;
use std::io::{self, Write};
use std::sync::atomic::{AtomicBool, Ordering};

use laparo_proto::text::printable;

/// Set by [`finish_when_closed`]: a closed pipe silences output instead of exiting.
static FINISH_WHEN_CLOSED: AtomicBool = AtomicBool::new(false);
/// Set once standard output was found closed under [`finish_when_closed`].
static CLOSED: AtomicBool = AtomicBool::new(false);

/// From now on a closed standard output silences the remaining lines instead of
/// ending the process, so that the command can close what it owns.
pub fn finish_when_closed() {
    FINISH_WHEN_CLOSED.store(true, Ordering::Relaxed);
}

/// Prints one line to standard output through [`line`](fn@line), as `println!` would.
macro_rules! say {
    () => {
        $crate::cmd::out::line(format_args!(""))
    };
    ($($arg:tt)*) => {
        $crate::cmd::out::line(format_args!($($arg)*))
    };
}
pub(crate) use say;

/// How the process ends after standard output failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ending {
    /// The reader closed the pipe: status 0, nothing said.
    Quiet,
    /// Anything else: status 1, with the error on stderr.
    Failed,
}

impl Ending {
    /// How a failed write to standard output ends the process.
    pub fn of(error: &io::Error) -> Ending {
        if error.kind() == io::ErrorKind::BrokenPipe {
            Ending::Quiet
        } else {
            Ending::Failed
        }
    }
}

/// Writes `args` and a newline to `w` and flushes it, so that a closed reader shows
/// at this line and not at exit. Whatever the line holds (a session id, a path, a
/// server's text), a character a terminal would act on is written escaped
/// ([`printable`]): every line of the client's output passes here.
pub fn write_line(w: &mut impl Write, args: fmt::Arguments<'_>) -> io::Result<()> {
    match args.as_str() {
        Some(text) => w.write_all(printable(text).as_bytes())?,
        None => w.write_all(printable(&args.to_string()).as_bytes())?,
    }
    w.write_all(b"\n")?;
    w.flush()
}

/// Writes one line to standard output; if that fails, ends the process as
/// [`Ending::of`] says.
pub fn line(args: fmt::Arguments<'_>) {
    if CLOSED.load(Ordering::Relaxed) {
        return;
    }
    if let Err(e) = write_line(&mut io::stdout().lock(), args) {
        match Ending::of(&e) {
            Ending::Quiet if FINISH_WHEN_CLOSED.load(Ordering::Relaxed) => {
                CLOSED.store(true, Ordering::Relaxed)
            }
            Ending::Quiet => std::process::exit(0),
            Ending::Failed => {
                tell(format_args!("laparo: cannot write to standard output: {e}"));
                std::process::exit(1)
            }
        }
    }
}

/// Writes one line to standard error, escaped as [`write_line`] does; a failure to
/// write it is ignored, where `eprintln!` would panic (status 101) with standard
/// error on a full disk or a closed pipe: there is nowhere left to say it, and the
/// exit status still tells.
pub fn tell(args: fmt::Arguments<'_>) {
    let _ = write_line(&mut io::stderr().lock(), args);
}

/// A log writer that writes each record as [`printable`] text: the tracing
/// subscriber formats a record (which may quote a server's text or a path) into
/// one buffer and writes it here at once, so escaping the buffer, but for the
/// newlines that end its lines, escapes every record. Colours are off for this
/// writer (their escape sequences would be written escaped).
pub struct EscapedLog<W: Write>(pub W);

impl<W: Write> Write for EscapedLog<W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let text = String::from_utf8_lossy(buf);
        for (k, line) in text.split('\n').enumerate() {
            if k > 0 {
                self.0.write_all(b"\n")?;
            }
            self.0.write_all(printable(line).as_bytes())?;
        }
        Ok(buf.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        self.0.flush()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_closed_pipe_ends_quietly_and_other_failures_do_not() {
        let (reader, mut writer) = io::pipe().unwrap();
        write_line(&mut writer, format_args!("first {}", 1)).unwrap();
        drop(reader);
        let e = write_line(&mut writer, format_args!("second")).unwrap_err();
        assert_eq!(Ending::of(&e), Ending::Quiet);
        let full = io::Error::from(io::ErrorKind::StorageFull);
        assert_eq!(Ending::of(&full), Ending::Failed);
    }

    #[test]
    fn a_line_ends_with_one_newline() {
        let mut buffer = Vec::new();
        write_line(&mut buffer, format_args!("a {} b", 2)).unwrap();
        write_line(&mut buffer, format_args!("")).unwrap();
        assert_eq!(buffer, b"a 2 b\n\n");
    }

    #[test]
    fn a_line_holding_terminal_controls_is_written_escaped() {
        let mut buffer = Vec::new();
        let session = "s1\u{1b}]0;PWN\u{7}\u{1b}[2J";
        write_line(&mut buffer, format_args!("joining session {session}")).unwrap();
        assert_eq!(
            String::from_utf8(buffer).unwrap(),
            "joining session s1\\u{1b}]0;PWN\\u{7}\\u{1b}[2J\n"
        );
    }

    #[test]
    fn a_log_record_is_written_escaped_but_for_its_line_ends() {
        let mut log = EscapedLog(Vec::new());
        log.write_all(b"WARN lost: \x1b[2Jgone\tnow\n").unwrap();
        log.write_all(b"two\nlines \xff\n").unwrap();
        assert_eq!(
            String::from_utf8(log.0).unwrap(),
            "WARN lost: \\u{1b}[2Jgone\\tnow\ntwo\nlines \u{FFFD}\n"
        );
    }
}

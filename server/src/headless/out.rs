//! What `laparo-server run` prints, and its messages on standard error, written so
//! that a stream that cannot be written ends nothing.
//!
//! `println!` and `eprintln!` panic when their stream fails: `laparo-server run … |
//! head -3` then stopped at its fourth line of progress with a backtrace and left
//! its time series and `--export` unwritten, and a server whose standard error went
//! to a full disk or a closed pipe panicked at the first line a service logged
//! (its caller saw "stream no longer needed", the session it created stayed). The
//! run's files and a server's sessions matter more than their progress lines: a
//! line that cannot be written is dropped, the first failure is kept, and the run
//! goes to its end. Then a closed pipe (`BrokenPipe`: the reader had what it
//! wanted) changes nothing, and any other failure (a full disk) is said on standard
//! error, if it can be, and makes the exit status 1.

use std::fmt;
use std::io::{self, Write};
use std::sync::Mutex;

/// The first failure to write standard output; once set, nothing more is written.
static FAILED: Mutex<Option<io::Error>> = Mutex::new(None);

/// Prints one line to standard output through [`line`](fn@line), as `println!`
/// would, without its panic.
#[macro_export]
macro_rules! say {
    ($($arg:tt)*) => {
        $crate::headless::out::line(format_args!($($arg)*))
    };
}

/// Writes `args` and a newline to standard output and flushes it (so that a closed
/// reader shows at this line); after a failure, nothing.
pub fn line(args: fmt::Arguments<'_>) {
    let mut failed = FAILED.lock().unwrap_or_else(|e| e.into_inner());
    if failed.is_some() {
        return;
    }
    if let Err(e) = write_line(&mut io::stdout().lock(), args) {
        *failed = Some(e);
    }
}

/// Writes `args` and a newline to `w` and flushes it.
pub fn write_line(w: &mut impl Write, args: fmt::Arguments<'_>) -> io::Result<()> {
    w.write_fmt(args)?;
    w.write_all(b"\n")?;
    w.flush()
}

/// Why standard output could not take every line, unless it was only closed by
/// its reader.
pub fn failure() -> Option<String> {
    let failed = FAILED.lock().unwrap_or_else(|e| e.into_inner());
    match &*failed {
        Some(e) if e.kind() != io::ErrorKind::BrokenPipe => Some(e.to_string()),
        _ => None,
    }
}

/// Writes one line to standard error; a failure to write it is ignored (there is
/// nowhere left to say it).
pub fn tell(args: fmt::Arguments<'_>) {
    let _ = write_line(&mut io::stderr().lock(), args);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_is_its_text_and_one_newline_and_a_closed_pipe_is_an_error_not_a_panic() {
        let (reader, mut writer) = io::pipe().unwrap();
        let mut buffer = Vec::new();
        write_line(&mut buffer, format_args!("tick {}", 3)).unwrap();
        assert_eq!(buffer, b"tick 3\n");
        drop(reader);
        let e = write_line(&mut writer, format_args!("gone")).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::BrokenPipe);
    }
}

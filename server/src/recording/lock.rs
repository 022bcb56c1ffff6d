//! A recording being written is locked, so that nothing takes it for a file left
//! by a stopped server.
//!
//! The recorder takes an exclusive `flock(2)` lock on its file as it creates it
//! ([`hold`]); the lock goes with the open file, so it ends when the recorder
//! closes it, and also when its server dies in any way (the kernel closes the
//! file). [`being_written`] asks for a shared lock without waiting: refused, the
//! file is held by a live recorder. `laparo recordings recover` refuses such a file
//! (rewriting it would replace the file the server goes on writing to, and the rest
//! of the session would go to a file no longer in the folder), and a local listing
//! shows it in progress rather than unfinished.
//!
//! The lock is advisory: it binds the tools that ask for it, which is all of
//! laparo's. On a file system without `flock` (some network mounts) it cannot be
//! taken, and a recording there is told apart as before: by the server that
//! writes it.

use std::fs::{File, TryLockError};
use std::path::Path;

/// Takes the recorder's lock on `file`, just created; a file system that refuses it
/// is logged, not fatal (the recording goes on, unlocked).
pub fn hold(file: &File, path: &Path) {
    if let Err(e) = file.try_lock() {
        tracing::warn!(
            "recording {}: cannot lock it ({e}); a recovery run while it is written \
             would not see that it is",
            path.display()
        );
    }
}

/// Whether a live recorder holds `file` (its lock refuses a shared one). The shared
/// lock, when granted, is released at once.
pub fn being_written(file: &File) -> bool {
    match file.try_lock_shared() {
        Ok(()) => {
            let _ = file.unlock();
            false
        }
        Err(TryLockError::WouldBlock) => true,
        Err(TryLockError::Error(_)) => false,
    }
}

/// [`being_written`] of the file at `path`, opened non-blocking (a FIFO put there
/// cannot hold the open); `false` when it cannot be opened.
pub fn path_being_written(path: &Path) -> bool {
    use std::os::unix::fs::OpenOptionsExt;
    File::options()
        .read(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(path)
        .is_ok_and(|f| being_written(&f))
}

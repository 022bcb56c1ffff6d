//! Where a recording's bytes come from: an open file read at positions, or bytes
//! held in memory; never a memory map.
//!
//! A map of a file that someone truncates or rewrites in place turns every later
//! access past the new end into SIGBUS, which kills the whole server, and no check
//! before the access can prevent it (the file may shrink between the check and the
//! access). Positional reads through the file handle cannot: a read past the end
//! returns short, which is an error here like any damaged length. So every read
//! asks for exactly the bytes of one record (a chunk, a metadata record, the
//! footer), checks its length against the file's size as it is now (`fstat` on the
//! handle), and reads it with `pread`: memory is one record at a time, bounded by
//! the caller, and a file changed under a reader gives a [`SourceError`], never a
//! signal. A file renamed over (what `recover` does) stays readable as it was: the
//! handle keeps the old file.
//!
//! Every byte read is counted ([`Source::bytes_read`]), so that tests can assert
//! what a listing or a replay reads rather than how long it takes.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::os::unix::fs::FileExt;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

use crate::engine::scene::open_nonblocking;

/// Why bytes could not be read.
#[derive(Debug, thiserror::Error)]
pub enum SourceError {
    /// The file is shorter than a record it states (or an index points to) needs:
    /// cut short, damaged, or changed in place while it is read.
    #[error(
        "it ends at byte {size}, before the {length} bytes at byte {at} it needs \
         (cut short, damaged, or changed while it was read)"
    )]
    Short { at: u64, length: u64, size: u64 },
    /// A length larger than any the reader accepts.
    #[error("a record at byte {at} states {length} bytes, more than the {limit} accepted")]
    TooLong { at: u64, length: u64, limit: u64 },
    #[error("{0}")]
    Io(#[from] std::io::Error),
}

enum Bytes {
    File(File),
    Held(Vec<u8>),
}

/// A recording's bytes, read a record at a time (see the module documentation).
pub struct Source {
    bytes: Bytes,
    read: AtomicU64,
}

impl std::fmt::Debug for Source {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Source")
            .field("held", &matches!(self.bytes, Bytes::Held(_)))
            .field("bytes_read", &self.bytes_read())
            .finish()
    }
}

/// How [`Source::open`] treats the last component of a path.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Follow {
    /// Through a symbolic link, as a user naming a file on the command line means.
    Links,
    /// Only the file itself: a symbolic link is refused (`O_NOFOLLOW`), so that a
    /// server serving a directory never reads outside it through one.
    NoLinks,
}

impl Source {
    /// Opens the regular file at `path`. Anything else (a directory, a FIFO, a
    /// device, and with [`Follow::NoLinks`] a symbolic link) is refused with
    /// `InvalidInput` before a byte is read; it is opened non-blocking, so that a
    /// FIFO cannot hold the open, and checked on the handle, so that nothing can be
    /// swapped in between the check and the reads.
    pub fn open(path: &Path, follow: Follow) -> std::io::Result<Self> {
        let file = open_nonblocking(path, follow == Follow::Links).map_err(|e| {
            if e.raw_os_error() == Some(libc::ELOOP) {
                std::io::Error::new(
                    std::io::ErrorKind::InvalidInput,
                    "it is a symbolic link, which is not followed",
                )
            } else {
                e
            }
        })?;
        if !file.metadata()?.is_file() {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                "it is not a regular file",
            ));
        }
        Ok(Source {
            bytes: Bytes::File(file),
            read: AtomicU64::new(0),
        })
    }

    /// Whether a live recorder is writing the file ([`super::lock`]); `false` for
    /// bytes held in memory.
    pub fn being_written(&self) -> bool {
        match &self.bytes {
            Bytes::File(f) => super::lock::being_written(f),
            Bytes::Held(_) => false,
        }
    }

    /// Bytes held in memory.
    pub fn held(bytes: Vec<u8>) -> Self {
        Source {
            bytes: Bytes::Held(bytes),
            read: AtomicU64::new(0),
        }
    }

    /// The size now, bytes (a file's, asked of its handle).
    #[allow(clippy::len_without_is_empty)] // a size that may change, asked once
    pub fn len(&self) -> std::io::Result<u64> {
        match &self.bytes {
            Bytes::File(f) => Ok(f.metadata()?.len()),
            Bytes::Held(b) => Ok(b.len() as u64),
        }
    }

    /// Bytes read so far.
    pub fn bytes_read(&self) -> u64 {
        self.read.load(Ordering::Relaxed)
    }

    /// Fills `buf` from byte `at`, or fails without a partial answer.
    pub fn read_exact_at(&self, at: u64, buf: &mut [u8]) -> Result<(), SourceError> {
        let length = buf.len() as u64;
        let short = |size| SourceError::Short { at, length, size };
        let size = self.len()?;
        if at.checked_add(length).is_none_or(|end| end > size) {
            return Err(short(size));
        }
        match &self.bytes {
            Bytes::File(f) => f.read_exact_at(buf, at).map_err(|e| {
                if e.kind() == std::io::ErrorKind::UnexpectedEof {
                    // Shrunk between the size asked and the read.
                    short(self.len().unwrap_or(0))
                } else {
                    SourceError::Io(e)
                }
            })?,
            Bytes::Held(b) => buf.copy_from_slice(&b[at as usize..(at + length) as usize]),
        }
        self.read.fetch_add(length, Ordering::Relaxed);
        Ok(())
    }

    /// The `length` bytes at `at`, at most `limit`: the length is checked against
    /// the limit and the size before anything is allocated.
    pub fn read_at(&self, at: u64, length: u64, limit: u64) -> Result<Vec<u8>, SourceError> {
        if length > limit {
            return Err(SourceError::TooLong { at, length, limit });
        }
        let size = self.len()?;
        if at.checked_add(length).is_none_or(|end| end > size) {
            return Err(SourceError::Short { at, length, size });
        }
        let mut buf = vec![0; length as usize];
        self.read_exact_at(at, &mut buf)?;
        Ok(buf)
    }

    /// A `Read + Seek` view, for readers that drive their own reads (the mcap
    /// crate's summary reader); its reads count as this source's.
    pub fn cursor(&self) -> Cursor<'_> {
        Cursor {
            source: self,
            at: 0,
        }
    }
}

/// See [`Source::cursor`].
pub struct Cursor<'a> {
    source: &'a Source,
    at: u64,
}

impl Read for Cursor<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let size = self.source.len()?;
        let n = (size.saturating_sub(self.at)).min(buf.len() as u64) as usize;
        self.source
            .read_exact_at(self.at, &mut buf[..n])
            .map_err(|e| match e {
                SourceError::Io(e) => e,
                e => std::io::Error::new(std::io::ErrorKind::UnexpectedEof, e.to_string()),
            })?;
        self.at += n as u64;
        Ok(n)
    }
}

impl Seek for Cursor<'_> {
    fn seek(&mut self, to: SeekFrom) -> std::io::Result<u64> {
        let base = match to {
            SeekFrom::Start(n) => Some(n),
            SeekFrom::End(d) => self.source.len()?.checked_add_signed(d),
            SeekFrom::Current(d) => self.at.checked_add_signed(d),
        };
        self.at = base.ok_or_else(|| {
            std::io::Error::new(std::io::ErrorKind::InvalidInput, "seek before the start")
        })?;
        Ok(self.at)
    }
}

#[cfg(test)]
mod tests;

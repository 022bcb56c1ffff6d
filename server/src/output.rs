//! Writing an output file whole or not at all.
//!
//! An output written in place is cut at whatever a failure leaves: `File::create`
//! truncates the old file first, so a full disk (ENOSPC) left `--export OUT.vtu`
//! and `--plot OUT.png` as files of 0 bytes, the earlier export or plot of that name
//! lost with them. [`WholeFile`] writes beside the output instead (`OUT.<pid>.part`,
//! created new) and renames it over the output once it is written and synced; until
//! then the output is as it was, and a part file not committed is removed. The
//! output must be a regular file or absent: a device, a symbolic link or a directory
//! is refused, never replaced.

use std::fs::File;
use std::io::{self, BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use crate::engine::scene::file_kind;

/// An output being written: a part file beside it, renamed over it by
/// [`commit`](Self::commit) and removed if dropped before.
#[derive(Debug)]
pub struct WholeFile {
    output: PathBuf,
    part: PathBuf,
    file: Option<BufWriter<File>>,
}

impl WholeFile {
    /// Starts writing `output`: refuses an output that exists and is not a regular
    /// file (`InvalidInput`, naming what it is), and creates the part file beside it.
    pub fn create(output: &Path) -> io::Result<Self> {
        writable_over(output)?;
        let part = part_path(output);
        let file = File::options().write(true).create_new(true).open(&part)?;
        Ok(WholeFile {
            output: output.to_path_buf(),
            part,
            file: Some(BufWriter::new(file)),
        })
    }

    /// The part file's path (`OUT.<pid>.part`).
    pub fn part(&self) -> &Path {
        &self.part
    }

    /// The part file, until committed.
    fn file(&mut self) -> &mut BufWriter<File> {
        self.file.as_mut().expect("a file is held until committed")
    }

    /// Flushes and syncs the part file and renames it over the output.
    pub fn commit(mut self) -> io::Result<()> {
        let file = self.file.take().expect("a file is held until committed");
        let file = file.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        std::fs::rename(&self.part, &self.output)
        // On an error the drop removes the part file.
    }
}

impl Write for WholeFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.file().write(buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.file().flush()
    }
}

impl Seek for WholeFile {
    fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
        self.file().seek(pos)
    }
}

impl Drop for WholeFile {
    fn drop(&mut self) {
        // Committed: the part file was renamed (or the rename failed, and it is
        // removed as well); not committed: an error or a panic stopped the writing.
        drop(self.file.take());
        let _ = std::fs::remove_file(&self.part);
    }
}

/// Refuses an output that exists and is not a regular file (`InvalidInput`, naming
/// what it is: a directory, a symbolic link, a device…); what [`WholeFile::create`]
/// checks first, for callers that check before a long run rather than after it.
pub fn writable_over(output: &Path) -> io::Result<()> {
    if let Ok(meta) = std::fs::symlink_metadata(output)
        && !meta.is_file()
    {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "will not write over {}: it is a {}, not a regular file",
                output.display(),
                file_kind(&meta)
            ),
        ));
    }
    Ok(())
}

/// The part file an output is written to before it is renamed over it:
/// `OUT.<pid>.part`, beside it.
pub fn part_path(output: &Path) -> PathBuf {
    let mut part = output.as_os_str().to_owned();
    part.push(format!(".{}.part", std::process::id()));
    PathBuf::from(part)
}

/// Writes `output` whole with `write`, or leaves it as it was.
pub fn write_whole(
    output: &Path,
    write: impl FnOnce(&mut WholeFile) -> io::Result<()>,
) -> io::Result<()> {
    let mut file = WholeFile::create(output)?;
    write(&mut file)?;
    file.commit()
}

#[cfg(test)]
mod tests;

//! ParaView data (`.pvd`): a time series of VTU files.
//!
//! `OUT.pvd` lists one `<DataSet timestep="t" file="OUT_000042.vtu"/>` per frame, the
//! VTU files beside it, named after it, paths relative to it so that the folder can
//! be moved.
//!
//! After every frame the `.pvd` on disk is a complete file listing every frame
//! written, so a run that stops early (killed, or the machine down) leaves a series
//! ParaView opens. Each frame's VTU is written and synced first; then the index is
//! written (the first frame: whole, renamed over an earlier index) or updated in
//! place: the frame's `DataSet` line and the closing tags are written in
//! one write over the previous closing tags (the file stays open between frames),
//! and the index is synced (`fdatasync`). A frame thus writes the same few hundred
//! bytes to the index whatever the number of frames before it, and a series of
//! [`MAX_FRAMES`] writes about 10 MB of index, not the index again every frame.

use std::fs::File;
use std::io::{self, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use super::vtu::write_vtu;
use crate::engine::simulation::Simulation;
use crate::output::{writable_over, write_whole};

/// Most frames one series may hold: a bound on the files a run writes.
pub const MAX_FRAMES: u64 = 100_000;

/// The index up to its first `DataSet`.
const HEAD: &str = "<?xml version=\"1.0\"?>\n\
    <VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n  <Collection>\n";
/// The index after its last `DataSet`.
const TAIL: &str = "  </Collection>\n</VTKFile>\n";

/// A time series being written.
#[derive(Debug)]
pub struct PvdSeries {
    path: PathBuf,
    stem: String,
    /// `(simulated time, VTU file name)` of each frame written.
    frames: Vec<(f64, String)>,
    /// The index, open once the first frame is written.
    index: Option<File>,
    /// Where the index's closing tags start: the next frame's line goes there.
    tail_at: u64,
}

impl PvdSeries {
    /// A series to be written to `path` (which should end in `.pvd`), with its frames
    /// beside it.
    pub fn new(path: &Path) -> Self {
        let stem = path
            .file_stem()
            .map_or_else(|| "frame".to_string(), |s| s.to_string_lossy().into_owned());
        PvdSeries {
            path: path.to_path_buf(),
            stem,
            frames: Vec::new(),
            index: None,
            tail_at: 0,
        }
    }

    /// Frames written so far.
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// Whether no frame was written.
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// The VTU files written so far, in time order.
    pub fn files(&self) -> Vec<PathBuf> {
        let dir = self.path.parent().unwrap_or(Path::new(""));
        self.frames.iter().map(|(_, f)| dir.join(f)).collect()
    }

    /// The file name of frame `i`, beside the index: `STEM_NNNNNN.vtu`.
    fn frame_name(&self, i: u64) -> String {
        format!("{}_{i:06}.vtu", self.stem)
    }

    /// Refuses, before a run, a series whose first `frames` frame names include
    /// one that exists and is not a regular file (a directory, a link, a device):
    /// writing that frame would stop the run there ([`writable_over`]).
    pub fn frames_writable(&self, frames: u64) -> io::Result<()> {
        let dir = self.path.parent().unwrap_or(Path::new(""));
        (0..frames.min(MAX_FRAMES)).try_for_each(|i| writable_over(&dir.join(self.frame_name(i))))
    }

    /// Whether `path` is where this series would write one of its frames, so that a
    /// run can refuse before it starts to write over a file it reads or another
    /// output (directories compared as resolved; `false` if either cannot be).
    pub fn may_write(&self, path: &Path) -> bool {
        let Some(name) = path.file_name().and_then(|n| n.to_str()) else {
            return false;
        };
        let Some(i) = name
            .strip_prefix(self.stem.as_str())
            .and_then(|r| r.strip_prefix('_'))
            .and_then(|r| r.strip_suffix(".vtu"))
            // Parsed loosely (`+1` reads as 1): rebuilding the name below refuses any
            // form but the six digits a frame is written with.
            .and_then(|d| d.parse::<u64>().ok())
        else {
            return false;
        };
        let dir = |p: &Path| {
            let d = p.parent().filter(|d| !d.as_os_str().is_empty());
            std::fs::canonicalize(d.unwrap_or(Path::new(".")))
        };
        i < MAX_FRAMES
            && self.frame_name(i) == name
            && matches!((dir(&self.path), dir(path)), (Ok(a), Ok(b)) if a == b)
    }

    /// Writes the simulation's current state as the next frame, at its simulated
    /// time, and adds it to the `.pvd` (created, or emptied, at the first frame).
    pub fn write_frame(&mut self, sim: &Simulation) -> io::Result<()> {
        if self.frames.len() as u64 >= MAX_FRAMES {
            return Err(io::Error::other(format!(
                "a series holds at most {MAX_FRAMES} frames"
            )));
        }
        let name = self.frame_name(self.frames.len() as u64);
        let dir = self.path.parent().unwrap_or(Path::new(""));
        write_vtu(sim, &dir.join(&name))?;
        self.append_to_index(sim.time, &name)?;
        self.frames.push((sim.time, name));
        Ok(())
    }

    /// Writes the line of a frame at `t` in `file` over the index's closing tags,
    /// and the closing tags after it, in one write; then syncs the index.
    fn append_to_index(&mut self, t: f64, file: &str) -> io::Result<()> {
        let line = format!(
            "    <DataSet timestep=\"{t:e}\" group=\"\" part=\"0\" file=\"{}\"/>\n",
            xml_escape(file)
        );
        let Some(index) = &mut self.index else {
            // The first frame writes the index whole, beside it, and renames it over
            // an earlier one (see `output`): a failure leaves that as it was.
            write_whole(&self.path, |w| {
                w.write_all(HEAD.as_bytes())?;
                w.write_all(line.as_bytes())?;
                w.write_all(TAIL.as_bytes())
            })?;
            self.index = Some(File::options().write(true).open(&self.path)?);
            self.tail_at = (HEAD.len() + line.len()) as u64;
            return Ok(());
        };
        let mut update = String::with_capacity(line.len() + TAIL.len());
        update.push_str(&line);
        update.push_str(TAIL);
        index.seek(SeekFrom::Start(self.tail_at))?;
        index.write_all(update.as_bytes())?;
        index.sync_data()?;
        self.tail_at += (update.len() - TAIL.len()) as u64;
        Ok(())
    }
}

/// `s` with the characters XML gives a meaning escaped, for an attribute value.
fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

#[cfg(test)]
mod tests;

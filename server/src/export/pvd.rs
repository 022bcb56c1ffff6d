//! ParaView data (`.pvd`): a time series of VTU files.
//!
//! `OUT.pvd` lists one `<DataSet timestep="t" file="OUT_000042.vtu"/>` per frame, the
//! VTU files beside it, named after it, paths relative to it so that the folder can
//! be moved. The `.pvd` is rewritten after every frame (it is small), so a run that
//! stops early still leaves a series ParaView opens.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use super::vtu::write_vtu;
use crate::engine::simulation::Simulation;

/// Most frames one series may hold: a bound on the files a run writes.
pub const MAX_FRAMES: u64 = 100_000;

/// A time series being written.
#[derive(Debug)]
pub struct PvdSeries {
    path: PathBuf,
    stem: String,
    /// `(simulated time, VTU file name)` of each frame written.
    frames: Vec<(f64, String)>,
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

    /// Writes the simulation's current state as the next frame, at its simulated
    /// time, and rewrites the `.pvd`.
    pub fn write_frame(&mut self, sim: &Simulation) -> io::Result<()> {
        if self.frames.len() as u64 >= MAX_FRAMES {
            return Err(io::Error::other(format!(
                "a series holds at most {MAX_FRAMES} frames"
            )));
        }
        let name = format!("{}_{:06}.vtu", self.stem, self.frames.len());
        let dir = self.path.parent().unwrap_or(Path::new(""));
        write_vtu(sim, &dir.join(&name))?;
        self.frames.push((sim.time, name));
        self.write_index()
    }

    fn write_index(&self) -> io::Result<()> {
        let mut w = BufWriter::new(File::create(&self.path)?);
        writeln!(w, r#"<?xml version="1.0"?>"#)?;
        writeln!(
            w,
            r#"<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">"#
        )?;
        writeln!(w, "  <Collection>")?;
        for (t, file) in &self.frames {
            writeln!(
                w,
                r#"    <DataSet timestep="{t:e}" group="" part="0" file="{}"/>"#,
                xml_escape(file)
            )?;
        }
        writeln!(w, "  </Collection>\n</VTKFile>")?;
        w.flush()?;
        w.into_inner().map_err(|e| e.into_error())?.sync_all()
    }
}

/// `s` with the characters XML gives a meaning escaped, for an attribute value.
fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

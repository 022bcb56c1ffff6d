//! Scripted instrument trajectories for headless runs: `--trajectory FILE.csv`.
//!
//! Format: one keyframe per line, comma-separated,
//! `t, instrument, tip_x, tip_y, tip_z, axis_x, axis_y, axis_z` — time in s, the
//! instrument's name as the scene declares it, tip `P` in m, axis `Z` (from the tip
//! toward the handle; any non-zero length, normalised on reading). A first line that
//! does not start with a number is a header; blank lines and lines starting with `#`
//! are skipped. Keyframes of one instrument must have increasing times.
//!
//! Between keyframes the tip moves linearly and the axis turns at constant angular
//! speed (spherical interpolation). Before an instrument's first keyframe it is out of
//! the body; after its last it holds its last pose.

use std::path::Path;

use nalgebra::{Point3, Unit, Vector3};

use crate::engine::contact::pose::InstrumentPose;

/// The largest coordinate accepted, m: anything farther is not in an operating room.
const ABSURD_DISTANCE: f64 = 100.0;

/// Why a trajectory could not be read; names the file and line.
#[derive(Debug, thiserror::Error)]
#[error("{source_name}:{line}: {message}")]
pub struct TrajectoryError {
    pub source_name: String,
    /// 1-based; 0 for faults of the whole file.
    pub line: usize,
    pub message: String,
}

/// One instrument's keyframes, in time order.
#[derive(Clone, Debug)]
pub struct Track {
    pub instrument: String,
    pub keys: Vec<(f64, InstrumentPose)>,
}

/// Keyframes for any number of instruments.
#[derive(Clone, Debug, Default)]
pub struct Trajectory {
    pub tracks: Vec<Track>,
}

impl Trajectory {
    /// Reads a trajectory file.
    pub fn load(path: &Path) -> Result<Self, TrajectoryError> {
        let name = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| TrajectoryError {
            source_name: name.clone(),
            line: 0,
            message: format!("cannot read: {e}"),
        })?;
        Self::parse(&text, &name)
    }

    /// Parses trajectory text; `source_name` names it in errors.
    pub fn parse(text: &str, source_name: &str) -> Result<Self, TrajectoryError> {
        let err = |line: usize, message: String| TrajectoryError {
            source_name: source_name.to_string(),
            line,
            message,
        };
        let mut traj = Trajectory::default();
        let mut first = true;
        for (k, raw) in text.lines().enumerate() {
            let line = k + 1;
            let row = raw.trim();
            if row.is_empty() || row.starts_with('#') {
                continue;
            }
            let fields: Vec<&str> = row.split(',').map(str::trim).collect();
            if first && fields[0].parse::<f64>().is_err() {
                first = false;
                continue;
            }
            first = false;
            if fields.len() != 8 {
                return Err(err(
                    line,
                    format!(
                        "expected 8 fields (t, instrument, tip x y z, axis x y z), found {}",
                        fields.len()
                    ),
                ));
            }
            let mut num = [0.0; 7];
            for (slot, (i, f)) in num
                .iter_mut()
                .zip(fields.iter().enumerate().filter(|(i, _)| *i != 1))
            {
                *slot = f
                    .parse::<f64>()
                    .map_err(|_| err(line, format!("field {} `{f}` is not a number", i + 1)))?;
                if !slot.is_finite() {
                    return Err(err(line, format!("field {} is not finite", i + 1)));
                }
            }
            let t = num[0];
            if t < 0.0 {
                return Err(err(line, format!("time {t} is negative")));
            }
            if t > super::MAX_RUN_SECONDS {
                return Err(err(
                    line,
                    format!(
                        "time {t:e} s is beyond the {:e} s a run may last",
                        super::MAX_RUN_SECONDS
                    ),
                ));
            }
            let tip = Point3::new(num[1], num[2], num[3]);
            if tip.coords.amax() > ABSURD_DISTANCE {
                return Err(err(
                    line,
                    format!("tip {tip} is more than {ABSURD_DISTANCE} m from the origin"),
                ));
            }
            let axis = Vector3::new(num[4], num[5], num[6]);
            let axis = Unit::try_new(axis, 1e-12)
                .ok_or_else(|| err(line, "the axis is zero".to_string()))?;
            let name = fields[1];
            if name.is_empty() {
                return Err(err(line, "the instrument name is empty".to_string()));
            }
            let track = match traj.tracks.iter_mut().position(|tr| tr.instrument == name) {
                Some(i) => &mut traj.tracks[i],
                None => {
                    traj.tracks.push(Track {
                        instrument: name.to_string(),
                        keys: Vec::new(),
                    });
                    traj.tracks.last_mut().unwrap()
                }
            };
            if let Some(&(last, _)) = track.keys.last()
                && t <= last
            {
                return Err(err(
                    line,
                    format!(
                        "time {t} of `{name}` does not come after its previous keyframe at {last}"
                    ),
                ));
            }
            track.keys.push((t, InstrumentPose::new(tip, axis)));
        }
        if traj.tracks.is_empty() {
            return Err(err(0, "no keyframes".to_string()));
        }
        Ok(traj)
    }

    /// The time of the last keyframe, s.
    pub fn end_time(&self) -> f64 {
        self.tracks
            .iter()
            .filter_map(|t| t.keys.last())
            .map(|k| k.0)
            .fold(0.0, f64::max)
    }

    /// For each of the scene's instruments, its track (if the file has one). A track
    /// naming an instrument the scene does not declare is an error.
    pub fn match_instruments(
        &self,
        names: &[&str],
        source_name: &str,
    ) -> Result<Vec<Option<usize>>, TrajectoryError> {
        for track in &self.tracks {
            if !names.contains(&track.instrument.as_str()) {
                return Err(TrajectoryError {
                    source_name: source_name.to_string(),
                    line: 0,
                    message: format!(
                        "instrument `{}` is not in the scene (it has: {})",
                        track.instrument,
                        names.join(", ")
                    ),
                });
            }
        }
        Ok(names
            .iter()
            .map(|n| self.tracks.iter().position(|t| t.instrument == *n))
            .collect())
    }
}

impl Track {
    /// The pose at time `t`: `None` before the first keyframe.
    pub fn pose_at(&self, t: f64) -> Option<InstrumentPose> {
        let first = self.keys.first()?;
        if t < first.0 {
            return None;
        }
        let k = self.keys.partition_point(|(kt, _)| *kt <= t);
        if k >= self.keys.len() {
            return Some(self.keys.last()?.1);
        }
        let ((t0, p0), (t1, p1)) = (self.keys[k - 1], self.keys[k]);
        Some(p0.lerp(&p1, (t - t0) / (t1 - t0)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const CSV: &str = "t,instrument,tip_x,tip_y,tip_z,axis_x,axis_y,axis_z\n\
        # a comment\n\
        0.0, left, 0, 0, 0.1, 0, 0, 1\n\
        1.0, left, 0, 0, 0.0, 0, 1, 0\n\
        0.5, right, 0.1, 0, 0, 0, 0, 2\n";

    #[test]
    fn interpolates_tip_linearly_and_axis_on_the_great_circle() {
        let tr = Trajectory::parse(CSV, "t.csv").unwrap();
        assert_eq!(tr.tracks.len(), 2);
        let left = &tr.tracks[0];
        assert!(left.pose_at(-0.1).is_none());
        let mid = left.pose_at(0.5).unwrap();
        assert!((mid.tip - Point3::new(0.0, 0.0, 0.05)).norm() < 1e-15);
        let diag = Vector3::new(0.0, 1.0, 1.0).normalize();
        assert!((mid.axis.into_inner() - diag).norm() < 1e-12);
        assert_eq!(left.pose_at(7.0).unwrap(), left.keys[1].1);
        // The axis was normalised on reading.
        assert!((tr.tracks[1].keys[0].1.axis.norm() - 1.0).abs() < 1e-15);
        assert_eq!(tr.end_time(), 1.0);
    }

    #[test]
    fn bad_rows_name_their_line() {
        let cases = [
            ("0, left, 0, 0, 0, 0, 0\n", 1, "expected 8 fields"),
            ("0, left, 0, 0, x, 0, 0, 1\n", 1, "not a number"),
            ("0, left, 0, 0, nan, 0, 0, 1\n", 1, "not finite"),
            ("0, left, 0, 0, 0, 0, 0, 0\n", 1, "axis is zero"),
            ("-1, left, 0, 0, 0, 0, 0, 1\n", 1, "negative"),
            ("0, left, 500, 0, 0, 0, 0, 1\n", 1, "from the origin"),
            (
                "t,i\n1, left, 0, 0, 0, 0, 0, 1\n1, left, 0, 0, 0, 0, 0, 1\n",
                3,
                "does not come after",
            ),
            ("0, , 0, 0, 0, 0, 0, 1\n", 1, "name is empty"),
        ];
        for (text, line, what) in cases {
            let e = Trajectory::parse(text, "t.csv").unwrap_err();
            assert_eq!(e.line, line, "{e}");
            assert!(
                e.to_string().starts_with(&format!("t.csv:{line}: ")) && e.message.contains(what),
                "{e}"
            );
        }
        assert!(
            Trajectory::parse("# nothing\n", "t.csv")
                .unwrap_err()
                .message
                .contains("no keyframes")
        );
    }

    #[test]
    fn unknown_instruments_are_refused() {
        let tr = Trajectory::parse(CSV, "t.csv").unwrap();
        assert_eq!(
            tr.match_instruments(&["right", "left"], "t.csv").unwrap(),
            vec![Some(1), Some(0)]
        );
        assert!(
            tr.match_instruments(&["left"], "t.csv")
                .unwrap_err()
                .message
                .contains("`right`")
        );
    }
}

//! Scripted instrument trajectories for headless runs: `--trajectory FILE.csv`.
//!
//! Format: one keyframe per line, comma-separated,
//! `t, instrument, tip_x, tip_y, tip_z, axis_x, axis_y, axis_z` — time in s, the
//! instrument's name as the scene declares it, tip `P` in m, axis `Z` (from the tip
//! toward the handle; any non-zero length, normalised on reading). A first line none
//! of whose fields but the second is a number is a header (a keyframe with a typo in
//! its time is an error naming it, not a header); blank lines and lines starting
//! with `#` are skipped, and a leading byte-order mark is ignored. Keyframes of one
//! instrument must have increasing times. A file names at most [`MAX_INSTRUMENTS`]
//! instruments (as many as a scene may have) and is at most
//! [`MAX_TRAJECTORY_BYTES`] long; it is read as scene and mesh files are
//! ([`read_bounded`]: a regular file only, so a FIFO or a device is refused rather
//! than read for ever).
//!
//! Between keyframes the tip moves linearly and the axis turns at constant angular
//! speed (spherical interpolation). Before an instrument's first keyframe it is out of
//! the body; after its last it holds its last pose.

use std::collections::HashMap;
use std::path::Path;

use laparo_proto::text::Number;
use nalgebra::{Point3, Unit, Vector3};

use crate::engine::contact::MAX_INSTRUMENTS;
use crate::engine::contact::pose::InstrumentPose;
use crate::engine::scene::read_bounded;

/// Whether the first line's `fields` are a header: none of those a keyframe holds
/// as numbers (all but the second, the instrument's name) is one.
fn is_header(fields: &[&str]) -> bool {
    fields
        .iter()
        .enumerate()
        .all(|(i, f)| i == 1 || f.parse::<f64>().is_err())
}

/// Largest trajectory file read, bytes: 16 MiB, about 250,000 keyframes (a keyframe
/// a millisecond for four instruments over a minute), held in memory as about as
/// many bytes again.
pub const MAX_TRAJECTORY_BYTES: u64 = 16 << 20;

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
    /// The line of its first keyframe (1-based), which errors about the instrument
    /// name.
    pub line: usize,
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
        let err = |message: String| TrajectoryError {
            source_name: name.clone(),
            line: 0,
            message,
        };
        let bytes =
            read_bounded(path, None, MAX_TRAJECTORY_BYTES).map_err(|e| err(e.to_string()))?;
        let text = String::from_utf8(bytes).map_err(|e| err(format!("not UTF-8 text: {e}")))?;
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
        // Track index by instrument name.
        let mut by_name: HashMap<&str, usize> = HashMap::new();
        let mut first = true;
        // A byte-order mark (written by some spreadsheets) is not part of the first
        // field: read as one, it made the first keyframe a header, dropped unsaid.
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        for (k, raw) in text.lines().enumerate() {
            let line = k + 1;
            let row = raw.trim();
            if row.is_empty() || row.starts_with('#') {
                continue;
            }
            let fields: Vec<&str> = row.split(',').map(str::trim).collect();
            if first && is_header(&fields) {
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
                return Err(err(line, format!("time {} is negative", Number(t))));
            }
            if t > super::MAX_RUN_SECONDS {
                return Err(err(
                    line,
                    format!(
                        "time {} s is beyond the {:e} s a run may last",
                        Number(t),
                        super::MAX_RUN_SECONDS
                    ),
                ));
            }
            let tip = Point3::new(num[1], num[2], num[3]);
            if tip.coords.amax() > ABSURD_DISTANCE {
                return Err(err(
                    line,
                    format!(
                        "tip ({}, {}, {}) is more than {ABSURD_DISTANCE} m from the origin",
                        Number(tip.x),
                        Number(tip.y),
                        Number(tip.z)
                    ),
                ));
            }
            let axis = unit_axis(Vector3::new(num[4], num[5], num[6]))
                .ok_or_else(|| err(line, "the axis is zero".to_string()))?;
            let name = fields[1];
            if name.is_empty() {
                return Err(err(line, "the instrument name is empty".to_string()));
            }
            let track = match by_name.get(name) {
                Some(&i) => &mut traj.tracks[i],
                None => {
                    if traj.tracks.len() >= MAX_INSTRUMENTS {
                        return Err(err(
                            line,
                            format!(
                                "instrument `{name}` is one more than the {MAX_INSTRUMENTS} \
                                 a scene may have"
                            ),
                        ));
                    }
                    by_name.insert(name, traj.tracks.len());
                    traj.tracks.push(Track {
                        instrument: name.to_string(),
                        line,
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
    /// naming an instrument the scene does not declare is an error naming the line
    /// of its first keyframe.
    pub fn match_instruments(
        &self,
        names: &[&str],
        source_name: &str,
    ) -> Result<Vec<Option<usize>>, TrajectoryError> {
        for track in &self.tracks {
            if !names.contains(&track.instrument.as_str()) {
                return Err(TrajectoryError {
                    source_name: source_name.to_string(),
                    line: track.line,
                    message: if names.is_empty() {
                        format!(
                            "instrument `{}` is not in the scene (it has none)",
                            track.instrument
                        )
                    } else {
                        format!(
                            "instrument `{}` is not in the scene (it has: {})",
                            track.instrument,
                            names.join(", ")
                        )
                    },
                });
            }
        }
        Ok(names
            .iter()
            .map(|n| self.tracks.iter().position(|t| t.instrument == *n))
            .collect())
    }
}

/// `v` scaled to unit length, `None` when it is zero. `v` is first divided by its
/// largest component, so that its squared norm neither overflows (a component above
/// about 1.3e154) nor underflows to zero (subnormal components): any finite non-zero
/// axis gives a finite unit vector.
fn unit_axis(v: Vector3<f64>) -> Option<Unit<Vector3<f64>>> {
    let largest = v.amax();
    if largest == 0.0 || !largest.is_finite() {
        return None;
    }
    Some(Unit::new_normalize(v / largest))
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
    fn an_unknown_instrument_is_named_at_the_line_it_first_appears() {
        let text = "t,i,x,y,z,ax,ay,az\n0, left, 0, 0, 0.1, 0, 0, 1\n\n\
            0.5, lift, 0, 0, 0.1, 0, 0, 1\n1, lift, 0, 0, 0.1, 0, 0, 1\n";
        let e = Trajectory::parse(text, "t.csv")
            .unwrap()
            .match_instruments(&["left"], "t.csv")
            .unwrap_err();
        assert_eq!(e.line, 4, "{e}");
        assert!(
            e.to_string().starts_with("t.csv:4: instrument `lift`"),
            "{e}"
        );
        // A scene with no instruments says so, not "(it has: )".
        let e = Trajectory::parse(text, "t.csv")
            .unwrap()
            .match_instruments(&[], "t.csv")
            .unwrap_err();
        assert!(
            e.message.ends_with("is not in the scene (it has none)"),
            "{e}"
        );
    }

    #[test]
    fn a_byte_order_mark_or_a_typo_in_the_first_time_loses_no_keyframe_unsaid() {
        // A byte-order mark before `0.0` made the first keyframe read as a header and
        // dropped it; a letter O for a zero did the same.
        let keys = "0.0, left, 0.0, 0.0, 0.055, 0, 0, 1\n1.0, left, 0.0, 0.0, 0.09, 0, 0, 1\n";
        let plain = Trajectory::parse(keys, "t.csv").unwrap();
        let marked = Trajectory::parse(&format!("\u{feff}{keys}"), "t.csv").unwrap();
        assert_eq!(marked.tracks[0].keys.len(), 2);
        assert_eq!(marked.tracks[0].keys, plain.tracks[0].keys);
        let typo = keys.replacen("0.0", "O.0", 1);
        let e = Trajectory::parse(&typo, "t.csv").unwrap_err();
        assert_eq!(e.line, 1, "{e}");
        assert!(e.message.contains("field 1 `O.0` is not a number"), "{e}");
        // A header still is one, marked or not.
        let header = format!("\u{feff}t, instrument, x, y, z, ax, ay, az\n{keys}");
        assert_eq!(
            Trajectory::parse(&header, "t.csv").unwrap().tracks[0]
                .keys
                .len(),
            2
        );
    }

    #[test]
    fn more_distinct_instruments_than_a_scene_holds_are_refused_at_the_first_extra() {
        // 40,000 names, each once: refused at the line of the ninth, so that neither
        // the tracks kept nor the work per line grows with the names in the file.
        let text: String = (0..40_000)
            .map(|k| format!("{k}, i{k}, 0, 0, 0, 0, 0, 1\n"))
            .collect();
        let e = match Trajectory::parse(&text, "t.csv") {
            Ok(tr) => panic!("read {} tracks", tr.tracks.len()),
            Err(e) => e,
        };
        assert_eq!(e.line, MAX_INSTRUMENTS + 1, "{e}");
        assert!(e.message.contains(&format!("`i{MAX_INSTRUMENTS}`")), "{e}");
        // As many as a scene may have are read.
        let eight: String = text
            .lines()
            .take(MAX_INSTRUMENTS)
            .map(|l| l.to_string() + "\n")
            .collect();
        assert_eq!(
            Trajectory::parse(&eight, "t.csv").unwrap().tracks.len(),
            MAX_INSTRUMENTS
        );
    }

    #[test]
    fn out_of_range_numbers_are_echoed_short() {
        // Written in full, each of these is over 300 digits.
        for (row, said) in [
            ("-1e300, left, 0, 0, 0, 0, 0, 1", "time -1e300 is negative"),
            (
                "1e300, left, 0, 0, 0, 0, 0, 1",
                "time 1e300 s is beyond the",
            ),
            (
                "0, left, 1e300, 0, -2.5e299, 0, 0, 1",
                "tip (1e300, 0, -2.5e299) is more than",
            ),
        ] {
            let e = Trajectory::parse(row, "t.csv").unwrap_err().to_string();
            assert!(e.contains(said) && e.len() < 200, "{row}: {e}");
        }
    }

    #[test]
    fn huge_and_tiny_axes_normalise_to_finite_unit_vectors() {
        let s3 = 1.0 / 3f64.sqrt();
        let s2 = 1.0 / 2f64.sqrt();
        let cases = [
            ("1e308, 1e308, 1e308", Vector3::new(s3, s3, s3)),
            ("-1.7976931348623157e308, 0, 0", -Vector3::x()),
            ("0, 2e154, 2e154", Vector3::new(0.0, s2, s2)),
            ("5e-324, 0, 5e-324", Vector3::new(s2, 0.0, s2)),
        ];
        for (axis, expected) in cases {
            let text = format!("0, left, 0, 0, 0, {axis}\n");
            let tr = Trajectory::parse(&text, "t.csv").unwrap_or_else(|e| panic!("{axis}: {e}"));
            let got = tr.tracks[0].keys[0].1.axis.into_inner();
            assert!((got - expected).norm() < 1e-15, "{axis}: {got}");
        }
    }

    #[test]
    fn load_reads_a_regular_file_within_the_limit_and_nothing_else() {
        let dir = std::env::temp_dir().join(format!("laparo-traj-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // Larger than the limit (sparse: nothing is written): refused, not read.
        let big = dir.join("big.csv");
        std::fs::File::create(&big)
            .unwrap()
            .set_len(MAX_TRAJECTORY_BYTES + 1)
            .unwrap();
        let e = Trajectory::load(&big).unwrap_err();
        assert!(e.message.contains("over the limit"), "{e}");
        let good = dir.join("good.csv");
        std::fs::write(&good, CSV).unwrap();
        assert_eq!(Trajectory::load(&good).unwrap().tracks.len(), 2);
        #[cfg(unix)]
        {
            // A device never ends; a FIFO with no writer would block the read.
            let e = Trajectory::load(Path::new("/dev/zero")).unwrap_err();
            assert!(e.message.contains("character device"), "{e}");
            let fifo = dir.join("fifo.csv");
            let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
            assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
            let e = Trajectory::load(&fifo).unwrap_err();
            assert!(e.to_string().contains("FIFO"), "{e}");
        }
        std::fs::remove_dir_all(dir).unwrap();
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

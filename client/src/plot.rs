//! `laparo replay --plot OUT.png`: the force on each instrument over simulated time,
//! drawn to a PNG.
//!
//! Plain data in, a picture out: [`force_series`] turns a recording's instrument
//! states into one [`ForceSeries`] per instrument (|force| at every tick and the
//! intervals in contact), and [`draw`] draws them: |force| in N against simulated
//! time in s, one colour per instrument, the contact intervals shaded behind the
//! curves and, below them, one lane per instrument filled while it touches the
//! liver. Text is set in DejaVu Sans, embedded, so the plot needs no font of the
//! system's.

use std::path::Path;
use std::sync::Once;

use laparo_proto::v1;
use laparo_server::output::WholeFile;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::{FontStyle, register_font};

/// One colour per instrument, in scene order (cycling): opaque, so that the
/// curves and the contact lanes are drawn in exactly these colours.
pub const COLORS: [(u8, u8, u8); 4] = [
    (31, 119, 180),
    (214, 39, 40),
    (44, 160, 44),
    (148, 103, 189),
];

/// How opaque the contact shading behind the curves is.
const SHADE_ALPHA: f64 = 0.12;

/// Default size of the picture, pixels.
pub const DEFAULT_SIZE: (u32, u32) = (1200, 600);

/// One instrument over a recording.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ForceSeries {
    pub instrument: String,
    /// `(simulated time s, |force| N)` at every recorded tick.
    pub force: Vec<(f64, f64)>,
    /// Intervals in contact (tip, shaft or both), `(from, to)` s: from the first
    /// tick in contact to the first tick out of it (the last tick, if none).
    pub contact: Vec<(f64, f64)>,
}

/// What a plot shows: its axes' ranges.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlotRanges {
    /// Simulated time, s.
    pub time_s: (f64, f64),
    /// |force|, N.
    pub force_n: (f64, f64),
}

/// Why a plot could not be made.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    #[error("cannot plot to {file}: the plot is a PNG, so its name must end in .png")]
    NotPng { file: String },
    #[error("cannot plot to {file}: {width}×{height} pixels is too small (at least 200×150)")]
    TooSmall {
        file: String,
        width: u32,
        height: u32,
    },
    #[error("cannot plot to {file}: {message}")]
    Draw { file: String, message: String },
}

/// Whether a plot could be written at `path`, as far as can be told before it is
/// drawn: a `.png` name, in a folder that exists, and not itself a folder. A
/// command that makes a plot asks first, so that a name that cannot be written is
/// refused before the command prints what it read (it was refused after).
pub fn check_target(path: &Path) -> Result<(), PlotError> {
    let file = || path.display().to_string();
    if !path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"))
    {
        return Err(PlotError::NotPng { file: file() });
    }
    let refused = |message: String| PlotError::Draw {
        file: file(),
        message,
    };
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    match std::fs::metadata(parent) {
        Ok(m) if m.is_dir() => {}
        Ok(_) => return Err(refused(format!("{} is not a folder", parent.display()))),
        Err(e) => return Err(refused(e.to_string())),
    }
    if path.is_dir() {
        return Err(refused("it is a folder".into()));
    }
    Ok(())
}

/// The series of recorded instrument states, in the order the instruments first
/// appear. Instruments that never had a pose (no station held them) are left out.
pub fn force_series<'a>(
    states: impl IntoIterator<Item = &'a v1::InstrumentState>,
) -> Vec<ForceSeries> {
    // (series, had a pose, contact began at)
    let mut out: Vec<(ForceSeries, bool, Option<f64>)> = Vec::new();
    for state in states {
        let k = match out
            .iter()
            .position(|(s, ..)| s.instrument == state.instrument)
        {
            Some(k) => k,
            None => {
                out.push((
                    ForceSeries {
                        instrument: state.instrument.clone(),
                        ..ForceSeries::default()
                    },
                    false,
                    None,
                ));
                out.len() - 1
            }
        };
        let (series, posed, began) = &mut out[k];
        let t = state.sim_time_s;
        let magnitude = state
            .force
            .as_ref()
            .and_then(|f| f.force.as_ref())
            .map_or(0.0, |f| (f.x * f.x + f.y * f.y + f.z * f.z).sqrt());
        series.force.push((t, magnitude));
        *posed |= state.pose.is_some();
        let touching = !matches!(
            v1::ContactState::try_from(state.contact),
            Ok(v1::ContactState::None | v1::ContactState::Unspecified) | Err(_)
        );
        match (touching, *began) {
            (true, None) => *began = Some(t),
            (false, Some(from)) => {
                series.contact.push((from, t));
                *began = None;
            }
            _ => {}
        }
    }
    out.into_iter()
        .filter(|(_, posed, _)| *posed)
        .map(|(mut series, _, began)| {
            if let (Some(from), Some(&(last, _))) = (began, series.force.last()) {
                series.contact.push((from, last));
            }
            series
        })
        .collect()
}

/// The data's ranges for `series`: time from the session's start (or the first
/// tick, if earlier) to the last tick, force from 0 to a tenth above the largest
/// (at least 0.1 N). [`draw`] adds room above for the legend.
pub fn ranges(series: &[ForceSeries]) -> PlotRanges {
    let points = || series.iter().flat_map(|s| s.force.iter());
    let (mut t0, mut t1) = points().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &(t, _)| {
        (a.min(t), b.max(t))
    });
    if !(t0.is_finite() && t1.is_finite()) {
        (t0, t1) = (0.0, 1.0);
    }
    t0 = t0.min(0.0);
    if t1 <= t0 {
        t1 = t0 + 1.0;
    }
    let max = points().map(|&(_, f)| f).fold(0.0, f64::max);
    PlotRanges {
        time_s: (t0, t1),
        force_n: (0.0, (1.1 * max).max(0.1)),
    }
}

/// The colour of the `k`-th series.
pub fn color(k: usize) -> RGBColor {
    let (r, g, b) = COLORS[k % COLORS.len()];
    RGBColor(r, g, b)
}

fn font() {
    static REGISTER: Once = Once::new();
    REGISTER.call_once(|| {
        // DejaVu Sans is a valid font: registering it cannot fail.
        let _ = register_font("sans-serif", FontStyle::Normal, dejavu::sans::regular());
    });
}

/// Draws `series` under `title` to the PNG `path`, `size` pixels (width, height);
/// returns the axes' ranges.
pub fn draw(
    series: &[ForceSeries],
    title: &str,
    path: &Path,
    size: (u32, u32),
) -> Result<PlotRanges, PlotError> {
    let file = path.display().to_string();
    check_target(path)?;
    if size.0 < 200 || size.1 < 150 {
        return Err(PlotError::TooSmall {
            file,
            width: size.0,
            height: size.1,
        });
    }
    font();
    let fail = |e: &dyn std::fmt::Display| PlotError::Draw {
        file: file.clone(),
        message: e.to_string(),
    };
    // Drawn in memory and written here, so that a path that cannot be written
    // says why in plain words.
    let mut pixels = vec![0u8; 3 * size.0 as usize * size.1 as usize];
    let ranges = {
        let root = BitMapBackend::with_buffer(&mut pixels, size).into_drawing_area();
        let ranges = draw_on(&root, series, title).map_err(|e| fail(&e))?;
        root.present().map_err(|e| fail(&e))?;
        ranges
    };
    write_png(path, size, &pixels).map_err(|e| fail(&e))?;
    Ok(ranges)
}

/// A plot read back: 8-bit RGB pixels, row by row.
#[derive(Clone, Debug)]
pub struct Picture {
    pub width: u32,
    pub height: u32,
    pub rgb: Vec<u8>,
}

impl Picture {
    /// Reads the PNG file at `path` (an 8-bit RGB one, as [`draw`] writes).
    pub fn read(path: &Path) -> Result<Picture, String> {
        let file = std::fs::File::open(path).map_err(|e| e.to_string())?;
        let mut reader = png::Decoder::new(std::io::BufReader::new(file))
            .read_info()
            .map_err(|e| e.to_string())?;
        let mut rgb = vec![0; reader.output_buffer_size()];
        let info = reader.next_frame(&mut rgb).map_err(|e| e.to_string())?;
        if (info.color_type, info.bit_depth) != (png::ColorType::Rgb, png::BitDepth::Eight) {
            return Err(format!(
                "{:?} {:?}, not 8-bit RGB",
                info.color_type, info.bit_depth
            ));
        }
        rgb.truncate(info.buffer_size());
        Ok(Picture {
            width: info.width,
            height: info.height,
            rgb,
        })
    }

    /// Every pixel: x, y, colour.
    pub fn pixels(&self) -> impl Iterator<Item = (u32, u32, [u8; 3])> + '_ {
        let width = self.width.max(1);
        self.rgb.chunks_exact(3).enumerate().map(move |(i, p)| {
            let i = i as u32;
            (i % width, i / width, [p[0], p[1], p[2]])
        })
    }
}

/// Writes 8-bit RGB `pixels` of `size` to the PNG file `path`, whole or not at all
/// (`laparo_server::output`: a failed write leaves an earlier plot of that name as
/// it was).
fn write_png(path: &Path, size: (u32, u32), pixels: &[u8]) -> Result<(), png::EncodingError> {
    let mut file = WholeFile::create(path)?;
    {
        let mut encoder = png::Encoder::new(&mut file, size.0, size.1);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder.write_header()?;
        writer.write_image_data(pixels)?;
        // Its end chunk, whose error a drop would not report.
        writer.finish()?;
    }
    file.commit()?;
    Ok(())
}

fn draw_on<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    series: &[ForceSeries],
    title: &str,
) -> Result<PlotRanges, DrawingAreaErrorKind<DB::ErrorType>> {
    root.fill(&WHITE)?;
    let (_, height) = root.dim_in_pixel();
    let text = |px: u32| ("sans-serif", px as f64).into_font();
    let scale = (height as f64 / 600.0).clamp(0.5, 3.0);
    let px = |n: f64| (n * scale).round() as u32;
    let lanes_height = px(22.0) * series.len().max(1) as u32 + px(50.0);
    let upper_height = height.saturating_sub(lanes_height);
    let (upper, lower) = root.split_vertically(upper_height);
    let data = ranges(series);
    let (t0, t1) = data.time_s;
    // Room above the curves for the legend (a row per instrument), so that it
    // never hides the largest force.
    let legend = (px(20.0) * series.len() as u32 + px(24.0)) as f64;
    let plot = upper_height.saturating_sub(px(60.0)).max(1) as f64;
    let (f0, f1) = (
        data.force_n.0,
        data.force_n.1 / (1.0 - (legend / plot).min(0.5)),
    );
    let lane_names: Vec<String> = series
        .iter()
        .map(|s| format!("{} in contact", s.instrument))
        .collect();
    let widest = lane_names
        .iter()
        .filter_map(|name| root.estimate_text_size(name, &text(px(14.0)).into()).ok())
        .map(|(w, _)| w)
        .max()
        .unwrap_or(0);
    let label_area = px(70.0).max(widest + px(16.0));

    let mut chart = ChartBuilder::on(&upper)
        .caption(title, text(px(22.0)))
        .margin(px(12.0))
        .margin_right(px(24.0))
        .x_label_area_size(px(8.0))
        .y_label_area_size(label_area)
        .build_cartesian_2d(t0..t1, f0..f1)?;
    chart
        .configure_mesh()
        .y_desc("|force| (N)")
        .axis_desc_style(text(px(16.0)))
        .label_style(text(px(14.0)))
        .x_labels(12)
        .y_labels(8)
        .x_label_formatter(&|_| String::new())
        .light_line_style(RGBColor(244, 244, 244))
        .bold_line_style(RGBColor(215, 215, 215))
        .draw()?;
    // All the shading first, so that it never covers a curve.
    for (k, s) in series.iter().enumerate() {
        let shade = color(k).mix(SHADE_ALPHA).filled();
        chart.draw_series(
            s.contact
                .iter()
                .map(|&(a, b)| Rectangle::new([(a, f0), (b, f1)], shade)),
        )?;
    }
    for (k, s) in series.iter().enumerate() {
        let style = color(k).stroke_width(2);
        let shade = color(k).mix(SHADE_ALPHA).filled();
        chart
            .draw_series(LineSeries::new(s.force.iter().copied(), style))?
            .label(format!("{}: |force|, shaded in contact", s.instrument))
            .legend(move |(x, y)| {
                EmptyElement::at((x, y))
                    + Rectangle::new([(0, -7), (20, 7)], shade)
                    + PathElement::new(vec![(0, 0), (20, 0)], style)
            });
    }
    if !series.is_empty() {
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .label_font(text(px(14.0)))
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(180, 180, 180))
            .draw()?;
    }

    // One lane per instrument below: filled while in contact.
    let n = series.len().max(1) as f64;
    let mut lanes = ChartBuilder::on(&lower)
        .margin(px(12.0))
        .margin_top(0)
        .margin_right(px(24.0))
        .x_label_area_size(px(40.0))
        .y_label_area_size(label_area)
        .build_cartesian_2d(t0..t1, 0.0..n)?;
    lanes
        .configure_mesh()
        .disable_mesh()
        .x_labels(12)
        .y_labels(0)
        .x_desc("simulated time (s)")
        .axis_desc_style(text(px(16.0)))
        .label_style(text(px(14.0)))
        .draw()?;
    for (k, s) in series.iter().enumerate() {
        let lane = n - 1.0 - k as f64;
        let fill = color(k).filled();
        lanes.draw_series(
            s.contact
                .iter()
                .map(|&(a, b)| Rectangle::new([(a, lane + 0.2), (b, lane + 0.8)], fill)),
        )?;
        // The lane's name, right-aligned left of it (root's pixels are the
        // backend's).
        let (x, y) = lanes.backend_coord(&(t0, lane + 0.5));
        root.draw(&Text::new(
            lane_names[k].clone(),
            (x - px(8.0) as i32, y),
            text(px(14.0))
                .color(&color(k))
                .pos(Pos::new(HPos::Right, VPos::Center)),
        ))?;
    }
    Ok(PlotRanges {
        time_s: (t0, t1),
        force_n: (f0, f1),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn state(
        name: &str,
        t: f64,
        force: f64,
        contact: v1::ContactState,
        posed: bool,
    ) -> v1::InstrumentState {
        v1::InstrumentState {
            sim_time_s: t,
            instrument: name.into(),
            pose: posed.then(v1::Pose::default),
            contact: contact as i32,
            force: Some(v1::Force {
                // 3-4-5: |force| is `force`.
                force: Some(v1::Vec3 {
                    x: 0.6 * force,
                    y: 0.0,
                    z: -0.8 * force,
                }),
                ..Default::default()
            }),
            ..Default::default()
        }
    }

    /// Two instruments over 10 ticks of 0.1 s: `a` touches from tick 2 to 4 and
    /// again from 7 to the end, `b` from 5 to 6; `c` never has a pose.
    fn states() -> Vec<v1::InstrumentState> {
        use v1::ContactState::{None, Shaft, Tip};
        let mut out = Vec::new();
        for k in 0..10 {
            let t = 0.1 * (k + 1) as f64;
            let a = (2..5).contains(&k) || k >= 7;
            let b = (5..7).contains(&k);
            out.push(state(
                "a",
                t,
                if a { 0.5 * k as f64 } else { 0.0 },
                if a { Tip } else { None },
                true,
            ));
            out.push(state(
                "b",
                t,
                if b { 1.0 } else { 0.0 },
                if b { Shaft } else { None },
                k > 0,
            ));
            out.push(state("c", t, 0.0, None, false));
        }
        out
    }

    #[test]
    fn series_hold_each_ticks_force_and_the_contact_intervals() {
        let states = states();
        let series = force_series(&states);
        let names: Vec<&str> = series.iter().map(|s| s.instrument.as_str()).collect();
        assert_eq!(names, ["a", "b"]);
        let (a, b) = (&series[0], &series[1]);
        assert_eq!(a.force.len(), 10);
        let t = |k: usize| 0.1 * (k + 1) as f64;
        for (k, &(time, f)) in a.force.iter().enumerate() {
            assert_eq!(time, t(k));
            let expected = if (2..5).contains(&k) || k >= 7 {
                0.5 * k as f64
            } else {
                0.0
            };
            assert!((f - expected).abs() < 1e-12, "tick {k}: {f}");
        }
        // Until the first tick out of contact; to the last tick when still in it.
        assert_eq!(a.contact, [(t(2), t(5)), (t(7), t(9))]);
        assert_eq!(b.contact, [(t(5), t(7))]);
        let r = ranges(&series);
        assert_eq!(r.time_s, (0.0, t(9)));
        assert!((r.force_n.1 - 1.1 * 4.5).abs() < 1e-12);
        assert_eq!(ranges(&[]).force_n, (0.0, 0.1));
    }

    fn temp(name: &str) -> std::path::PathBuf {
        std::env::temp_dir().join(format!("laparo-plot-{}-{name}", std::process::id()))
    }

    /// Pixels of `rgb` in rows `rows` of `image`.
    fn count(image: &Picture, rgb: (u8, u8, u8), rows: std::ops::Range<u32>) -> usize {
        image
            .pixels()
            .filter(|&(_, y, p)| rows.contains(&y) && p == [rgb.0, rgb.1, rgb.2])
            .count()
    }

    #[test]
    fn each_series_is_drawn_in_its_colour() {
        let states = states();
        let series = force_series(&states);
        let path = temp("two.png");
        let r = draw(&series, "two instruments", &path, (640, 400)).unwrap();
        let data = ranges(&series);
        assert_eq!(r.time_s, data.time_s);
        // The data's range, and room above it for the legend.
        assert!(r.force_n.0 == 0.0 && r.force_n.1 > data.force_n.1);
        assert!(r.force_n.1 < 2.0 * data.force_n.1);
        let image = Picture::read(&path).unwrap();
        let _ = std::fs::remove_file(&path);
        assert_eq!((image.width, image.height), (640, 400));
        for (k, &rgb) in COLORS[..2].iter().enumerate() {
            // A curve across the time axis, not just its legend's sample.
            let n = count(&image, rgb, 0..400);
            assert!(n > 320, "{n} pixels of series {k}'s colour");
        }
        // Nothing in the colour of a third series.
        assert_eq!(count(&image, COLORS[2], 0..400), 0);
        // Text was drawn: dark pixels in the title's band.
        let title = image
            .pixels()
            .filter(|&(_, y, p)| y < 30 && p.iter().all(|&c| c < 100))
            .count();
        assert!(title > 50, "{title} dark pixels in the title");
    }

    #[test]
    fn a_path_that_cannot_be_written_is_a_clear_error() {
        let series = force_series(&states());
        let missing = temp("no-such-dir").join("forces.png");
        let e = draw(&series, "t", &missing, DEFAULT_SIZE).unwrap_err();
        assert!(matches!(e, PlotError::Draw { .. }), "{e}");
        let text = e.to_string();
        assert!(text.contains(&missing.display().to_string()), "{text}");
        let e = draw(&series, "t", &temp("forces.jpg"), DEFAULT_SIZE).unwrap_err();
        assert!(matches!(e, PlotError::NotPng { .. }), "{e}");
        assert!(e.to_string().contains(".png"));
        let e = draw(&series, "t", &temp("tiny.png"), (100, 100)).unwrap_err();
        assert!(matches!(e, PlotError::TooSmall { .. }), "{e}");
        assert!(!temp("forces.jpg").exists() && !temp("tiny.png").exists());
    }
}

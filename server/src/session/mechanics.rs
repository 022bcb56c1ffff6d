//! The mechanics thread of a session: a plain OS thread ticking at the scene's rate.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Weak};
use std::thread::JoinHandle;
use std::time::{Duration, Instant, SystemTime};

use laparo_proto::v1;
use tokio::sync::{broadcast, watch};

use super::{Session, SessionStats, Slot};
use crate::engine::simulation::Simulation;
use crate::frame::{Frame, Holder, TickOutputs};
use crate::recording::{Item, Recorder, Report};

/// The longest wall time between two reports of the tick times (and looks at the
/// idle timeout) while the ticks run slower than their period; at the scene's rate
/// they come once a simulated second.
const REPORT_EVERY: Duration = Duration::from_secs(1);

/// What the thread owns.
pub(super) struct Mechanics {
    pub sim: Simulation,
    pub inputs: Vec<triple_buffer::Output<Slot>>,
    pub frames: watch::Sender<Arc<Frame>>,
    pub events: broadcast::Sender<v1::Event>,
    pub stats: Arc<SessionStats>,
    pub stop: Arc<AtomicBool>,
    pub session: Weak<Session>,
    pub recorder: Option<Arc<Recorder>>,
}

pub(super) fn spawn(m: Mechanics) -> std::io::Result<JoinHandle<()>> {
    std::thread::Builder::new()
        .name("mechanics".into())
        .spawn(move || {
            let recorder = m.recorder.clone();
            m.run();
            // The ticks are over: the recorder writes what it holds and closes the file.
            if let Some(r) = recorder {
                let _ = r.finish();
            }
        })
}

impl Mechanics {
    /// Tells the live streams what the recorder reported.
    fn report(&self, report: Option<Report>) {
        if let Some(report) = report {
            let _ = self.events.send(report.event(self.sim.tick, self.sim.time));
        }
    }

    /// Ticks at the scene's rate until stopped: deadlines are `start + k·dt`; a tick
    /// that starts more than a period late counts as missed, and the schedule
    /// resynchronises instead of bursting to catch up.
    fn run(mut self) {
        // Closing stops a tick between substeps or CG iterations, however long it is.
        self.sim.integrator.set_interrupt(self.stop.clone());
        let dt = Duration::from_secs_f64(self.sim.dt);
        let n = self.sim.instruments.len();
        let mut holders = vec![Holder::default(); n];
        let mut outputs = TickOutputs::new(n);
        // A tick's contact events (at most one per instrument), held until its frame
        // is known finite: a tick that halts the session publishes nothing.
        let mut pending = Vec::with_capacity(n);
        let mut tick_ms: Vec<f64> = Vec::with_capacity(256);
        let mut idle_since: Option<Instant> = None;
        let mut next = Instant::now();
        let mut reported = next;
        while !self.stop.load(Ordering::Relaxed) {
            let now = Instant::now();
            if now < next {
                std::thread::sleep(next - now);
            } else if now - next > dt {
                let late = ((now - next).as_secs_f64() / self.sim.dt) as u64;
                self.stats
                    .missed_deadlines
                    .fetch_add(late, Ordering::Relaxed);
                next = now;
            }
            next += dt;
            let started = Instant::now();
            for (k, input) in self.inputs.iter_mut().enumerate() {
                match *input.read() {
                    Slot::Untouched => {}
                    Slot::Pose(p) => {
                        self.sim.set_pose(k, Some(p.pose));
                        holders[k] = Holder {
                            station: Some(p.station),
                            pose_sequence: Some(p.sequence),
                        };
                    }
                    Slot::Withdrawn => {
                        self.sim.set_pose(k, None);
                        holders[k] = Holder::default();
                    }
                }
            }
            self.sim.tick();
            if self.stop.load(Ordering::Relaxed) {
                // Closing cut the tick short: it is not published.
                break;
            }
            pending.clear();
            let frame = outputs.produce(&self.sim, |k| holders[k], |event| pending.push(event));
            if let Some(fault) = super::first_fault(&frame.surface, &frame.instruments) {
                self.halt(fault, idle_since);
                break;
            }
            let recorder = self.recorder.as_deref();
            for event in pending.drain(..) {
                super::broadcast_event(recorder, &self.events, event);
            }
            let frame = Arc::new(frame);
            if let Some(r) = &self.recorder {
                let report = r.offer(Item::Frame {
                    frame: frame.clone(),
                    wall: SystemTime::now(),
                });
                self.report(report);
            }
            self.frames.send_replace(frame);
            self.stats.tick.store(self.sim.tick, Ordering::Relaxed);
            self.stats
                .sim_time_bits
                .store(self.sim.time.to_bits(), Ordering::Relaxed);
            let now = Instant::now();
            tick_ms.push((now - started).as_secs_f64() * 1e3);
            // Once a second of ticks, or of wall time when the ticks are slower than
            // their period: a scene whose ticks take 30 s (as much work as a tick may
            // have) would otherwise report its tick times and look at its idle
            // timeout once every 30 minutes.
            if tick_ms.len() as f64 * self.sim.dt >= 1.0 || now - reported >= REPORT_EVERY {
                reported = now;
                tick_ms.sort_by(f64::total_cmp);
                let at = |q: f64| tick_ms[((tick_ms.len() - 1) as f64 * q).round() as usize];
                self.stats
                    .tick_p50_bits
                    .store(at(0.5).to_bits(), Ordering::Relaxed);
                self.stats
                    .tick_p99_bits
                    .store(at(0.99).to_bits(), Ordering::Relaxed);
                tick_ms.clear();
                // Close when nobody has been connected for the idle timeout.
                if !self.check_idle(&mut idle_since, now) {
                    break;
                }
            }
        }
    }

    /// Closes the session when nobody has been connected to it for its idle timeout
    /// (`idle_since`: since when nobody is); `false` once the session is gone.
    pub(super) fn check_idle(&self, idle_since: &mut Option<Instant>, now: Instant) -> bool {
        let Some(session) = self.session.upgrade() else {
            return false;
        };
        if session.stats.connected.load(Ordering::Relaxed) == 0 {
            let since = *idle_since.get_or_insert(now);
            if session.idle_timeout.is_some_and(|t| now - since >= t) {
                session.close("idle timeout");
            }
        } else {
            *idle_since = None;
        }
        true
    }
}

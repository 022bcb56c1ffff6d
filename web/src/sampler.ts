// The driven instruments' poses sampled at the station's pose rate, and sent in
// batches: one Station.SendPoses call carries the samples taken since the last.
//
// Input (mouse, wheel, keys, gamepad) moves a Driver between animation frames.
// At each frame the sampler takes the samples due since the last one, at times
// t_k = t_0 + k·Δ with Δ = 1 / rateHz, each with the driver's pivot and
// insertion interpolated linearly between where they were at the last frame and
// where they are now:
//
//   q(t_k) = q_prev + (q_now − q_prev) · (t_k − t_prev) / (t_now − t_prev)
//
// so a station in the browser poses the instrument as `laparo station` does (at
// its default 250 Hz, or the server's limit if lower), however fast the display
// runs. The poses wait in a
// bounded queue while a call is in flight; a stalled connection drops the
// oldest rather than grow the page's memory.
import type { Driver, Vec } from "./drive";

/** Poses per second per instrument: `laparo station`'s default pose rate. */
export const POSE_RATE_HZ = 250;
/** Poses one SendPoses call may carry (the server's MAX_POSES_PER_CALL). */
export const MAX_POSES_PER_CALL = 64;
/** Samples taken at most per frame, per instrument: after a long pause (a
 * hidden tab), only the newest quarter second is sampled. */
const MAX_SAMPLES_PER_FRAME = MAX_POSES_PER_CALL;
/** Poses kept waiting for a call, in all: four calls' worth. */
export const MAX_PENDING = 4 * MAX_POSES_PER_CALL;

export interface Sample {
  instrument: string;
  tip: Vec;
  axis: Vec;
  /** When the pose holds, ms on the page's clock (performance.now()). */
  t: number;
}

interface Was {
  yaw: number;
  pitch: number;
  depth: number;
}

export class PoseSampler {
  /** Time of the next sample, ms; NaN before the first frame. */
  private next = NaN;
  private last = NaN;
  private was = new Map<string, Was>();
  /** Poses waiting for a SendPoses call, oldest first. */
  readonly pending: Sample[] = [];
  /** Samples dropped because the queue was full. */
  dropped = 0;

  constructor(public rateHz = POSE_RATE_HZ) {}

  /** Samples at POSE_RATE_HZ, or at the server's limit (`Joined.max_pose_rate_hz`,
   * 0 when it does not say) if that is lower: a station above it spends its burst
   * allowance in seconds, then has poses refused and loses its stream. */
  limitTo(serverLimitHz: number): void {
    this.rateHz = serverLimitHz > 0 && Number.isFinite(serverLimitHz) ? Math.min(POSE_RATE_HZ, serverLimitHz) : POSE_RATE_HZ;
  }

  /** Takes the samples due at `now` (ms) of every driver into the queue. */
  take(now: number, drivers: Map<string, Driver>): void {
    const dt = 1000 / this.rateHz;
    if (Number.isNaN(this.next)) {
      // The first frame: one sample, now.
      this.next = now;
      this.last = now;
    }
    if (now - this.next > MAX_SAMPLES_PER_FRAME * dt) {
      this.next = now - (MAX_SAMPLES_PER_FRAME - 1) * dt;
      this.last = Math.min(this.last, this.next);
    }
    for (; this.next <= now; this.next += dt) {
      const s = now > this.last ? (this.next - this.last) / (now - this.last) : 1;
      for (const [name, d] of drivers) {
        const w = this.was.get(name) ?? { yaw: d.yaw, pitch: d.pitch, depth: d.depth };
        const p = d.poseAt(w.yaw + (d.yaw - w.yaw) * s, w.pitch + (d.pitch - w.pitch) * s, w.depth + (d.depth - w.depth) * s);
        this.push({ instrument: name, tip: p.tip, axis: p.axis, t: this.next });
      }
    }
    this.last = now;
    for (const [name, d] of drivers) this.was.set(name, { yaw: d.yaw, pitch: d.pitch, depth: d.depth });
  }

  /** Up to MAX_POSES_PER_CALL of the oldest waiting poses, taken off the queue. */
  batch(): Sample[] {
    return this.pending.splice(0, MAX_POSES_PER_CALL);
  }

  private push(s: Sample): void {
    if (this.pending.length >= MAX_PENDING) {
      this.pending.shift();
      this.dropped++;
    }
    this.pending.push(s);
  }
}

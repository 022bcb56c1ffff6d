// Driving an instrument without a haptic device, as a laparoscopic instrument
// moves: about its trocar. The pose is the trocar-fixed pivot (yaw, pitch of the
// axis about its rest direction, the line from the liver's centre to the
// trocar), the insertion depth d from the trocar to the tip, and the roll
// (shown; the contract's pose has no roll: the instruments are cylinders).
//
//   axis Z = unit(cos p cos y · z0 + cos p sin y · u + sin p · v)   tip → handle
//   tip  P = trocar − d · Z
//
// with z0 the rest direction and (u, v) a basis perpendicular to it.
// Mouse drag pivots, the wheel inserts, Q/E roll; a gamepad's sticks pivot both
// instruments, its triggers insert (pulling back with the shoulder button of
// their side held) and its shoulder buttons alone roll.
import type { InstrumentDescription } from "./gen/laparo/v1/scene_pb";

export interface Vec { x: number; y: number; z: number }

const sub = (a: Vec, b: Vec): Vec => ({ x: a.x - b.x, y: a.y - b.y, z: a.z - b.z });
const dot = (a: Vec, b: Vec) => a.x * b.x + a.y * b.y + a.z * b.z;
const cross = (a: Vec, b: Vec): Vec => ({ x: a.y * b.z - a.z * b.y, y: a.z * b.x - a.x * b.z, z: a.x * b.y - a.y * b.x });
const scale = (a: Vec, s: number): Vec => ({ x: a.x * s, y: a.y * s, z: a.z * s });
const add = (a: Vec, b: Vec): Vec => ({ x: a.x + b.x, y: a.y + b.y, z: a.z + b.z });
const unit = (a: Vec): Vec => scale(a, 1 / Math.sqrt(dot(a, a)));

/** Largest pivot from the rest direction, rad: the body wall limits it. */
export const MAX_PIVOT_RAD = (60 * Math.PI) / 180;
/** Pivot per pixel dragged, rad. */
export const RAD_PER_PIXEL = 0.003;
/** Insertion per wheel unit (a notch is ~100), m. */
export const M_PER_WHEEL = 0.00005;

export class Driver {
  yaw = 0;
  pitch = 0;
  roll = 0;
  depth: number;
  readonly trocar: Vec;
  private readonly z0: Vec;
  private readonly u: Vec;
  private readonly v: Vec;

  /** Starts pointing at `center` with the tip `standoff` m before it. */
  constructor(readonly instrument: InstrumentDescription, center: Vec, standoff: number) {
    const t = instrument.trocar ?? { x: 0, y: 0, z: 0 };
    this.trocar = { x: t.x, y: t.y, z: t.z };
    const toTrocar = sub(this.trocar, center);
    const distance = Math.sqrt(dot(toTrocar, toTrocar));
    this.z0 = distance > 1e-9 ? scale(toTrocar, 1 / distance) : { x: 0, y: 0, z: 1 };
    const up = Math.abs(this.z0.y) < 0.9 ? { x: 0, y: 1, z: 0 } : { x: 1, y: 0, z: 0 };
    this.u = unit(cross(up, this.z0));
    this.v = cross(this.z0, this.u);
    this.depth = Math.max(0, distance - standoff);
  }

  pivot(dYaw: number, dPitch: number): void {
    this.yaw = clamp(this.yaw + dYaw, -MAX_PIVOT_RAD, MAX_PIVOT_RAD);
    this.pitch = clamp(this.pitch + dPitch, -MAX_PIVOT_RAD, MAX_PIVOT_RAD);
  }

  insert(dDepth: number): void {
    this.depth = clamp(this.depth + dDepth, 0, this.instrument.lengthM);
  }

  /** The axis Z (tip toward handle) and the tip P. */
  pose(): { tip: Vec; axis: Vec } {
    return this.poseAt(this.yaw, this.pitch, this.depth);
  }

  /** The axis and tip at pivot (yaw, pitch) and insertion depth, m. */
  poseAt(yaw: number, pitch: number, depth: number): { tip: Vec; axis: Vec } {
    const cp = Math.cos(pitch);
    const axis = unit(add(add(scale(this.z0, cp * Math.cos(yaw)), scale(this.u, cp * Math.sin(yaw))), scale(this.v, Math.sin(pitch))));
    return { tip: sub(this.trocar, scale(axis, depth)), axis };
  }
}

function clamp(x: number, lo: number, hi: number): number {
  return Math.min(hi, Math.max(lo, x));
}

/** A stick's value with its dead zone removed. */
export function stick(v: number): number {
  const DEAD = 0.12;
  return Math.abs(v) < DEAD ? 0 : (v - Math.sign(v) * DEAD) / (1 - DEAD);
}

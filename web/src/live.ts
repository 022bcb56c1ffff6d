// The live view of a session: observing (Observe.Observe) or driving instruments
// (Station.Attach + Station.SendPoses, gRPC-web's form of Station.Join; the poses
// sampled at the station's pose rate and sent in batches, see sampler.ts). The
// stream is read into "newest" slots and drawn once per animation frame, so a
// fast stream never queues draws; a lost connection is said and retried with
// backoff; a wrong token, a closed or unknown session, an eviction end the view
// with a notice.
import { create } from "@bufbuild/protobuf";
import { Code, failure, observe, sessions, station } from "./api";
import { Driver, M_PER_WHEEL, RAD_PER_PIXEL, stick } from "./drive";
import { PoseSampler } from "./sampler";
import { DevicePoseSchema } from "./gen/laparo/v1/station_pb";
import { EventKind } from "./gen/laparo/v1/event_pb";
import type { Event } from "./gen/laparo/v1/event_pb";
import type { InstrumentState, SurfaceFrame } from "./gen/laparo/v1/frame_pb";
import type { SceneDescription } from "./gen/laparo/v1/scene_pb";
import { Role } from "./gen/laparo/v1/session_pb";
import { backoff, clearNotice, el, notice, setConnection, sleep } from "./status";
import { SceneView } from "./view/scene3d";
import { Gauges } from "./view/gauges";
import { FrameClock } from "./view/frameclock";
import { clientName, DEFAULT_NAME, givenName, MAX_NAME_BYTES, setGivenName } from "./name";

export interface LiveOptions {
  sessionId: string;
  /** Instruments to drive; empty: observe. */
  instruments: string[];
  /** The view this one replaces in place (the token changed): its instruments
   * resume where it left them, as after a reconnect. */
  resume?: Handover;
}

/** What a live view passes on to the view that replaces it: the drivers of its
 * instruments, and when its session was created (SessionInfo.created_at; null
 * before it was known), which tells the same session from another given its id
 * by a restarted server. */
export interface Handover {
  sessionId: string;
  opened: string | null;
  drivers: Map<string, Driver>;
}

/** Interval between writes of the page's text (status line, gauges, data- attributes), ms. */
const TEXT_MS = 100;

/** Where the tip starts, m before the liver's centre: outside its surface. */
const STANDOFF_FRACTION_OF_RADIUS = 1.0;

/** Instruments one page drives: the first and, with shift (or a gamepad's second
 * stick and trigger), the second. More would be claimed from every other station
 * and never moved. */
export const MAX_DRIVEN = 2;

export function live(root: HTMLElement, asked: LiveOptions, signal: AbortSignal): Handover {
  const left = asked.instruments.slice(MAX_DRIVEN);
  const options = { ...asked, instruments: asked.instruments.slice(0, MAX_DRIVEN) };
  const driving = options.instruments.length > 0;
  const viewport = el("div", { class: "viewport", id: "viewport" });
  const hud = el("div", { class: "status", id: "hud" });
  const gauges = new Gauges();
  const events = el("ul", { id: "events" });
  const scopeButton = el("button", { id: "scope", type: "button" }, "laparoscope");
  // The name the station joins with, shown in the sessions table: changed, the
  // station joins again under it, the instruments kept where they are.
  const nameInput = el("input", {
    id: "client-name",
    type: "text",
    placeholder: DEFAULT_NAME,
    title: `the name this station shows in the sessions table, kept in this tab, a new tab starting with the last one given in this browser (empty: "${DEFAULT_NAME}"); changing it joins again under the new name, the instruments kept where they are; over ${MAX_NAME_BYTES} bytes it is cut to fit`,
  });
  nameInput.value = givenName();
  const side = el(
    "div",
    { class: "side" },
    el("h3", { title: driving ? options.instruments.join(", ") : "" }, driving ? `driving ${options.instruments.join(", ")}` : "observing"),
    el("p", { title: options.sessionId }, `session ${options.sessionId}`),
    driving ? el("p", {}, el("label", { class: "name" }, "name ", nameInput)) : "",
    left.length > 0
      ? el("p", { id: "not-driven" }, `not claimed: ${left.join(", ")} (a page drives ${MAX_DRIVEN} instruments; open another page for the rest)`)
      : "",
    gauges.root,
    el("p", { class: "controls" }, scopeButton),
    driving ? el("p", {}, "drag or arrow keys: pivot about the trocar · wheel or W/S: insert · Q/E: roll · shift: the second instrument · right-drag: orbit · gamepad: sticks, triggers, shoulders") : "",
    hud,
    el("h4", {}, "events"),
    events,
  );
  const page = el("div", { class: "live", id: "live", "data-session": options.sessionId, "data-mode": driving ? "drive" : "observe" }, viewport, side);
  root.replaceChildren(page);
  const view = new SceneView(viewport);
  signal.addEventListener("abort", () => view.dispose());
  scopeButton.addEventListener("click", () => {
    view.useScope = !view.useScope;
    view.redraw();
  });

  // Newest of each, set by the stream, used by the frame loop.
  let surface: SurfaceFrame | null = null;
  const states = new Map<string, InstrumentState>();
  /** Newest |F| of each instrument, N (for the gamepad's vibration). */
  const forceN = new Map<string, number>();
  let scene: SceneDescription | null = null;
  const drivers = new Map<string, Driver>();
  const resume = options.resume;
  if (resume && resume.sessionId === options.sessionId && resume.opened !== null) {
    for (const [name, d] of resume.drivers) if (options.instruments.includes(name)) drivers.set(name, d);
  }
  const handover: Handover = { sessionId: options.sessionId, opened: drivers.size > 0 ? resume!.opened : null, drivers };
  let handle = "";
  let sequence = 0n;
  const sentAt = new Map<string, { seq: bigint; t: number }>();
  const stats = { tick: 0n, frames: 0, skipped: 0, ticksPerFrame: 1, rate: 0, latencyMs: NaN, firstFrameMs: NaN };
  let rateWindow: { t: number; tick: bigint } | null = null;
  let sending = false;
  let active = false;

  function onScene(desc: SceneDescription, frameRateHz: number): void {
    scene = desc;
    view.setScene(desc);
    gauges.set(desc.instruments.map((i) => i.name));
    const mech = desc.summary?.mechanicsRateHz ?? 60;
    stats.ticksPerFrame = Math.max(1, Math.round(mech / frameRateHz));
    page.dataset.scene = desc.summary?.name ?? "";
    // A reconnect offers the scene again: an instrument it still has keeps its
    // Driver, so it resumes where the trainee left it, not at its start pose.
    for (const name of drivers.keys()) {
      if (!desc.instruments.some((d) => d.name === name)) drivers.delete(name);
    }
    const positions = desc.restSurface?.positions ?? [];
    let cx = 0, cy = 0, cz = 0;
    const n = positions.length / 3;
    for (let i = 0; i < positions.length; i += 3) {
      cx += positions[i] / n;
      cy += positions[i + 1] / n;
      cz += positions[i + 2] / n;
    }
    let radius = 0;
    for (let i = 0; i < positions.length; i += 3) {
      radius = Math.max(radius, Math.hypot(positions[i] - cx, positions[i + 1] - cy, positions[i + 2] - cz));
    }
    for (const d of desc.instruments) {
      if (options.instruments.includes(d.name) && !drivers.has(d.name)) {
        drivers.set(d.name, new Driver(d, { x: cx, y: cy, z: cz }, STANDOFF_FRACTION_OF_RADIUS * radius));
      }
    }
  }

  function onSurface(f: SurfaceFrame): void {
    if (surface && f.tick > surface.tick + BigInt(stats.ticksPerFrame)) {
      stats.skipped += Number(f.tick - surface.tick) / stats.ticksPerFrame - 1;
    }
    surface = f;
    stats.frames++;
    const now = performance.now();
    if (!rateWindow) rateWindow = { t: now, tick: f.tick };
    else if (now - rateWindow.t > 1000) {
      stats.rate = (Number(f.tick - rateWindow.tick) * 1000) / (now - rateWindow.t);
      rateWindow = { t: now, tick: f.tick };
    }
  }

  function onState(s: InstrumentState): void {
    states.set(s.instrument, s);
    forceN.set(s.instrument, s.force?.magnitudeN ?? 0);
    const sent = sentAt.get(s.instrument);
    if (sent && s.poseSequence !== undefined && s.poseSequence >= sent.seq) {
      stats.latencyMs = performance.now() - sent.t;
      sentAt.delete(s.instrument);
    }
  }

  function onEvent(e: Event): void {
    const station = e.stationId !== undefined ? `station ${e.stationId}` : "";
    const item = el("li", {}, [`${e.simTimeS.toFixed(2)} s`, EventKind[e.kind] ?? String(e.kind), station, e.instrument ?? "", e.detail].filter(Boolean).join(" "));
    events.prepend(item);
    while (events.childElementCount > 30) events.lastElementChild?.remove();
    if (e.kind === EventKind.SESSION_CLOSING) closed = `session ${options.sessionId} closed: ${e.detail}`;
  }

  let closed: string | null = null;

  const sampler = new PoseSampler();
  const sendStats = { calls: 0, poses: 0, lastBatch: 0, spacingMs: NaN };

  /** When the last SendPoses call was answered, ms on the page's clock. */
  let lastCallAt = -Infinity;

  // The heartbeat: poses are sampled at each animation frame, and a hidden tab
  // draws none, so a page whose tab is hidden would go silent and lose its
  // instruments after the server's station timeout (5 s by default). A call
  // with no poses every second keeps the station (timers still run in a hidden
  // tab, once a second at least); the instruments stay where they were.
  const HEARTBEAT_MS = 1000;
  const beat = setInterval(() => {
    if (!handle || sending || performance.now() - lastCallAt < HEARTBEAT_MS) return;
    sending = true;
    station
      .sendPoses({ handle, poses: [] }, { signal })
      .then(() => (lastCallAt = performance.now()))
      .catch(() => {}) // the Attach stream says what went wrong
      .finally(() => (sending = false));
  }, HEARTBEAT_MS);
  signal.addEventListener("abort", () => clearInterval(beat));

  /** What sendPoses last said went wrong: cleared once a call succeeds again. */
  let posesNotice: string | null = null;
  /** Failed SendPoses calls in a row, and when the next may be made (ms on the
   * page's clock): after a failure, not before its backoff, rather than at
   * every frame while the network is down. Poses sampled meanwhile wait in the
   * sampler (the oldest dropped past its bound). */
  let posesFailed = 0;
  let posesRetryAt = -Infinity;

  /** The current join (Station.Attach), ended to join again under a new name. */
  let join: AbortController | null = null;
  let renaming = false;
  /** Joins the page ended itself to join again under a new name: a batch sent
   * for one of their stations fails for that alone. */
  const rejoined = new WeakSet<AbortController>();

  /** Sends the waiting poses, a batch per call, one call at a time. */
  async function sendPoses(): Promise<void> {
    if (!handle || sending || sampler.pending.length === 0 || performance.now() < posesRetryAt) return;
    sending = true;
    /** The join whose station the batch in flight is for. */
    let sentFor: AbortController | null = null;
    try {
      while (sampler.pending.length > 0 && handle && !signal.aborted) {
        sentFor = join;
        const batch = sampler.batch();
        const poses = batch.map((p) => {
          sequence++;
          if (!sentAt.has(p.instrument)) sentAt.set(p.instrument, { seq: sequence, t: p.t });
          return create(DevicePoseSchema, { instrument: p.instrument, pose: { tip: p.tip, axis: p.axis }, deviceTimeS: p.t / 1000, sequence });
        });
        await station.sendPoses({ handle, poses }, { signal });
        posesFailed = 0;
        if (posesNotice !== null) clearNotice(posesNotice);
        posesNotice = null;
        sendStats.calls++;
        lastCallAt = performance.now();
        sendStats.poses += poses.length;
        sendStats.lastBatch = poses.length;
        const per = drivers.size;
        if (batch.length > per) sendStats.spacingMs = (batch[batch.length - 1].t - batch[0].t) / (batch.length / per - 1);
      }
    } catch (e) {
      const f = failure(e);
      // The station was ended by our own rejoin under a new name while the
      // batch was on its way (the server no longer knows its handle): no
      // failure to say nor to back off from; the new station is sent the
      // poses sampled from its joining.
      if (f.code === Code.NotFound && sentFor !== null && rejoined.has(sentFor)) return;
      posesRetryAt = performance.now() + backoff(posesFailed++);
      // A call answered after the view ended (closed, evicted) would hide why it did.
      if (f.code !== undefined && !signal.aborted && !closed) {
        posesNotice = `poses not sent: ${f.text}`;
        notice(posesNotice);
      }
    } finally {
      sending = false;
    }
  }

  // Input: mouse drag or the arrow keys pivot the first instrument driven
  // (shift: the second), the wheel or W/S insert, Q/E roll. Right-drag orbits
  // (OrbitControls).
  view.controls.mouseButtons = driving
    ? { LEFT: null as unknown as never, MIDDLE: 1, RIGHT: 0 } // RIGHT: ROTATE, MIDDLE: DOLLY
    : view.controls.mouseButtons;
  view.controls.enableZoom = !driving;
  const canvas = view.renderer.domElement;
  let dragging: { x: number; y: number } | null = null;
  const target = (shift: boolean) => [...drivers.values()][shift && drivers.size > 1 ? 1 : 0];
  if (driving) {
    canvas.addEventListener("pointerdown", (e) => {
      if (e.button === 0) dragging = { x: e.clientX, y: e.clientY };
    });
    // A drag ends however the button comes up: released (over the page or
    // not), cancelled, the pointer capture lost, or the window left (a release
    // outside it is never seen); and any move with the primary button up ends
    // it too, so a missed release never leaves hovering pivoting the instrument.
    const endDrag = () => (dragging = null);
    window.addEventListener("pointerup", endDrag, { signal });
    window.addEventListener("pointercancel", endDrag, { signal });
    window.addEventListener("blur", endDrag, { signal });
    canvas.addEventListener("lostpointercapture", endDrag);
    canvas.addEventListener("pointermove", (e) => {
      if (!dragging) return;
      if ((e.buttons & 1) === 0) {
        dragging = null;
        return;
      }
      target(e.shiftKey)?.pivot(-(e.clientX - dragging.x) * RAD_PER_PIXEL, -(e.clientY - dragging.y) * RAD_PER_PIXEL);
      dragging = { x: e.clientX, y: e.clientY };
    });
    canvas.addEventListener(
      "wheel",
      (e) => {
        e.preventDefault();
        // Shift+wheel comes as a horizontal scroll on macOS and in some Chrome
        // setups (deltaX, deltaY zero): either one inserts the second instrument.
        target(e.shiftKey)?.insert((e.shiftKey ? e.deltaY || e.deltaX : e.deltaY) * M_PER_WHEEL);
      },
      { passive: false },
    );
    window.addEventListener(
      "keydown",
      (e) => {
        // Keys typed into a field (the token, say) are the field's, not the instrument's.
        if (e.target instanceof HTMLElement && (e.target.isContentEditable || e.target.closest("input, select, textarea"))) return;
        // Ctrl+W, Cmd+S and the like are the browser's.
        if (e.ctrlKey || e.metaKey || e.altKey) return;
        const d = target(e.shiftKey);
        if (!d) return;
        // Driving by keyboard alone (shift: the second instrument): the arrows
        // pivot, W/S (or PageDown/PageUp) insert and pull back, Q/E roll; held
        // down, a key repeats. The arrows and pages would otherwise scroll.
        const key = e.key.length === 1 ? e.key.toLowerCase() : e.key;
        const RAD_PER_KEY = 0.02;
        const M_PER_KEY = 0.002;
        switch (key) {
          case "q": d.roll -= 0.1; break;
          case "e": d.roll += 0.1; break;
          case "ArrowLeft": d.pivot(RAD_PER_KEY, 0); break;
          case "ArrowRight": d.pivot(-RAD_PER_KEY, 0); break;
          case "ArrowUp": d.pivot(0, RAD_PER_KEY); break;
          case "ArrowDown": d.pivot(0, -RAD_PER_KEY); break;
          case "w": case "PageDown": d.insert(M_PER_KEY); break;
          case "s": case "PageUp": d.insert(-M_PER_KEY); break;
          default: return;
        }
        e.preventDefault();
      },
      { signal },
    );
  }

  function gamepad(): void {
    const pad = navigator.getGamepads?.().find((g) => g && g.connected);
    if (!pad || drivers.size === 0) return;
    const list = [...drivers.values()];
    const [l, r] = [list[0], list[1] ?? list[0]];
    const RATE = 0.02;
    l.pivot(-stick(pad.axes[0] ?? 0) * RATE, -stick(pad.axes[1] ?? 0) * RATE);
    if (list[1]) r.pivot(-stick(pad.axes[2] ?? 0) * RATE, -stick(pad.axes[3] ?? 0) * RATE);
    // The standard mapping: the left stick pivots the first instrument, the right
    // stick the second; a trigger inserts its side's instrument (LT the first, RT
    // the second); its shoulder button held with it pulls it back instead, and
    // held alone rolls it (LB the first, RB the second), so pulling back never rolls.
    const b = (i: number) => pad.buttons[i]?.value ?? 0;
    const pressed = (i: number) => pad.buttons[i]?.pressed ?? false;
    const INSERT = 0.0005;
    l.insert(b(6) * INSERT * (pressed(4) ? -1 : 1));
    if (list[1]) r.insert(b(7) * INSERT * (pressed(5) ? -1 : 1));
    if (pressed(4) && !pressed(6)) l.roll -= 0.05;
    if (pressed(5) && !pressed(7)) r.roll += 0.05;
    // Vibration growing with the force, where the pad has an actuator.
    let force = 0;
    for (const name of drivers.keys()) force = Math.max(force, forceN.get(name) ?? 0);
    const actuator = (pad as Gamepad & { vibrationActuator?: { playEffect?: (t: string, p: object) => Promise<unknown> } }).vibrationActuator;
    if (force > 0.05 && actuator?.playEffect) {
      actuator.playEffect("dual-rumble", { duration: 50, strongMagnitude: Math.min(1, force / 5), weakMagnitude: Math.min(1, force / 2) }).catch(() => {});
    }
  }

  const clock = new FrameClock();
  let shownAt = -Infinity;

  function frame(now: number): void {
    if (signal.aborted) return;
    requestAnimationFrame(frame);
    clock.begin();
    if (driving && active) {
      gamepad();
      sampler.take(performance.now(), drivers);
      void sendPoses();
    }
    if (surface) {
      view.setSurface(surface.positions);
      stats.tick = surface.tick;
      surface = null;
    }
    for (const s of states.values()) {
      view.setInstrument(s);
      gauges.update(s, drivers.has(s.instrument));
    }
    states.clear();
    clock.beginRender();
    const drew = view.draw();
    clock.endRender();
    if (drew && scene && Number.isNaN(stats.firstFrameMs) && view.drawn > 0) {
      stats.firstFrameMs = performance.now();
      page.dataset.firstFrameMs = stats.firstFrameMs.toFixed(0);
    }
    // The page's text, a few times a second: each write costs a layout.
    if (now - shownAt >= TEXT_MS) {
      shownAt = now;
      showText();
    }
    clock.end(page);
  }

  function showText(): void {
    gauges.show((name) => view.heldDrawn(name));
    page.dataset.tick = String(stats.tick);
    page.dataset.frames = String(stats.frames);
    page.dataset.drawn = String(view.drawn);
    // Geometries on the GPU: the same after a reconnect as before it.
    page.dataset.geometries = String(view.renderer.info.memory.geometries);
    page.dataset.maxDisplacementMm = (view.maxDisplacement * 1000).toFixed(3);
    page.dataset.surfaceChangeMm = (view.maxChange * 1000).toFixed(3);
    if (driving) {
      page.dataset.poseCalls = String(sendStats.calls);
      page.dataset.posesSent = String(sendStats.poses);
      page.dataset.poseSpacingMs = sendStats.spacingMs.toFixed(3);
      page.dataset.posesDropped = String(sampler.dropped);
    }
    const roll = [...drivers.entries()].map(([n, d]) => `${n} roll ${((d.roll * 180) / Math.PI).toFixed(0)}°`).join(" ");
    hud.textContent =
      `tick ${stats.tick} · mechanics ${stats.rate.toFixed(1)} Hz · latency ${Number.isNaN(stats.latencyMs) ? "–" : stats.latencyMs.toFixed(0) + " ms"}` +
      ` · frames ${stats.frames} · skipped ${Math.round(stats.skipped)} · max displacement ${(view.maxDisplacement * 1000).toFixed(1)} mm ${roll}`;
  }
  requestAnimationFrame(frame);

  nameInput.addEventListener("change", () => {
    const before = clientName();
    // What is kept is what is sent: trimmed, and cut to the server's limit.
    nameInput.value = setGivenName(nameInput.value);
    if (clientName() === before || !join) return;
    renaming = true;
    rejoined.add(join);
    join.abort();
  });

  void (async () => {
    for (let attempt = 0; !signal.aborted; attempt++) {
      setConnection(attempt === 0 ? "connecting" : "reconnecting");
      try {
        // Ids start again at s1 when the server restarts: a session of the id
        // found on a reconnect may be another one. Its creation time tells.
        const info = await sessions.getSession({ sessionId: options.sessionId }, { signal });
        const created = `${info.createdAt?.seconds ?? ""}.${info.createdAt?.nanos ?? ""}`;
        if (handover.opened === null) handover.opened = created;
        else if (created !== handover.opened) {
          closed = `session ${options.sessionId} ended (the server restarted; ${options.sessionId} is now another session)`;
          break;
        }
        if (driving) {
          const mine = new AbortController();
          join = mine;
          const stop = () => mine.abort();
          signal.addEventListener("abort", stop, { once: true });
          mine.signal.addEventListener("abort", () => signal.removeEventListener("abort", stop), { once: true });
          const stream = station.attach(
            { sessionId: options.sessionId, role: Role.TRAINEE, instruments: options.instruments, clientName: clientName() },
            { signal: mine.signal },
          );
          for await (const m of stream) {
            if (m.kind.case === "attached") {
              handle = m.kind.value.handle;
              continue;
            }
            const k = m.kind.value?.kind;
            if (!k) continue;
            switch (k.case) {
              case "joined":
                if (k.value.scene) onScene(k.value.scene, k.value.surfaceFrameRateHz);
                sampler.limitTo(k.value.maxPoseRateHz);
                page.dataset.poseRateHz = String(sampler.rateHz);
                // Poses sampled for a station that is gone are not sent to the new one.
                sampler.pending.length = 0;
                posesFailed = 0;
                posesRetryAt = -Infinity;
                active = true;
                attempt = 0;
                notice(null);
                setConnection("live");
                break;
              case "surfaceFrame":
                onSurface(k.value);
                break;
              case "instrumentState":
                onState(k.value);
                break;
              case "event":
                onEvent(k.value);
                break;
              case "error":
                notice(`pose rejected: ${k.value.message}`);
                break;
            }
          }
        } else {
          for await (const m of observe.observe({ sessionId: options.sessionId }, { signal })) {
            const k = m.kind;
            switch (k.case) {
              case "scene":
                onScene(k.value, k.value.summary?.mechanicsRateHz ?? 60);
                attempt = 0;
                notice(null);
                setConnection("live");
                break;
              case "surfaceFrame":
                onSurface(k.value);
                break;
              case "instrumentState":
                onState(k.value);
                break;
              case "event":
                onEvent(k.value);
                break;
            }
          }
        }
        if (closed) break;
        // The stream ended without a reason: the server went away; try again.
        throw new Error("the stream ended");
      } catch (e) {
        active = false;
        handle = "";
        join?.abort();
        join = null;
        if (signal.aborted) return;
        if (closed) break;
        if (renaming) {
          // Ended to join again under the name just given: at once, not as a failure.
          renaming = false;
          attempt = -1;
          continue;
        }
        const f = e instanceof Error && e.message === "the stream ended" ? { text: "the stream ended", retry: true, auth: false, code: undefined } : failure(e);
        // The server ends a closing session's streams with UNAVAILABLE and
        // "session closed: reason", possibly before the SESSION_CLOSING event.
        const reason = /session closed: (.*)/.exec(f.text);
        if (reason) {
          closed = `session ${options.sessionId} closed: ${reason[1]}`;
          break;
        }
        if (f.evicted) {
          // Ends the view: rejoining by itself would undo the eviction.
          closed = `${f.text}; reload the page to join again`;
          break;
        }
        const unknown = /has no instrument `(.*)`/.exec(f.text);
        if (f.code === Code.NotFound && unknown) {
          // The address asks for an instrument the scene lacks: the session is there.
          closed = `instrument ${unknown[1]} is not in the scene of session ${options.sessionId} (${f.text})`;
          break;
        }
        if (f.code === Code.NotFound) {
          // Gone while away (closed, idle, or the server restarted without it).
          closed = `session ${options.sessionId} is closed or does not exist (${f.text})`;
          break;
        }
        if (!f.retry) {
          setConnection("error", f.text);
          // Only another token helps an unknown one; a token refused a right
          // (to claim this instrument, say) is valid.
          notice(f.code === Code.Unauthenticated ? `${f.text} — enter a token above` : f.text);
          page.dataset.error = f.text;
          return;
        }
        const wait = backoff(attempt);
        setConnection("reconnecting", `${f.text}; again in ${(wait / 1000).toFixed(1)} s`);
        notice(`${f.text}; reconnecting in ${(wait / 1000).toFixed(1)} s`);
        await sleep(wait, signal);
      }
    }
    if (closed) {
      setConnection("ended", closed);
      notice(closed);
    }
  })();
  return handover;
}

// The replay page: a recording through Recordings.Replay — play, pause, speed,
// seek, recorded or re-simulated — drawn as the live view draws, with |force|
// over time beside it. Pausing ends the stream; playing again (or seeking, or
// changing the speed or mode) opens a new one from the time reached. Seeking
// while paused, or after the end, opens one only for the frame at the time
// sought, and stays paused; a speed changed then is kept for the next play.
// A lost connection is retried with the live view's backoff, from the time reached.
import { Code, failure, recordings } from "./api";
import type { InstrumentState, SurfaceFrame } from "./gen/laparo/v1/frame_pb";
import { ReplayMode } from "./gen/laparo/v1/recording_pb";
import { ForcePlot } from "./view/plot";
import { SceneView } from "./view/scene3d";
import { Gauges } from "./view/gauges";
import { backoff, el, notice, setConnection, sleep } from "./status";

/** Interval between writes of the page's text (time, gauges, plot), ms. */
const TEXT_MS = 100;

/** Attempts at a replay the server refuses for its limit (RESOURCE_EXHAUSTED,
 * `--max-replays`) before saying so: a seek or a change of speed aborts the
 * stream and opens another, and the server frees the aborted one's slot only a
 * moment later. */
const SLOT_ATTEMPTS = 4;

export function replay(root: HTMLElement, file: string, signal: AbortSignal): void {
  const viewport = el("div", { class: "viewport", id: "viewport" });
  const play = el("button", { id: "play", type: "button" }, "play");
  const pause = el("button", { id: "pause", type: "button" }, "pause");
  const speed = el("select", { id: "speed" }, ...["0.25", "0.5", "1", "2", "4", "10"].map((s) => el("option", { value: s }, `${s}×`)));
  speed.value = "1";
  const resim = el("input", { id: "resimulate", type: "checkbox" });
  const seek = el("input", { id: "seek", type: "range", min: "0", max: "1", step: "0.01", value: "0" });
  const time = el("span", { id: "time" }, "0.0 s");
  const plot = new ForcePlot();
  const gauges = new Gauges();
  const page = el(
    "div",
    { class: "live", id: "replay", "data-file": file, "data-state": "loading" },
    viewport,
    el(
      "div",
      { class: "side" },
      el("h3", { title: file }, `replay ${file}`),
      el("p", { class: "controls" }, play, pause, speed, el("label", {}, resim, " re-simulated")),
      el("p", {}, seek, " ", time),
      gauges.root,
      el("h4", {}, "|force| over time"),
      plot.canvas,
    ),
  );
  root.replaceChildren(page);
  const view = new SceneView(viewport);
  signal.addEventListener("abort", () => view.dispose());

  let duration = 0;
  let at = 0; // simulated time reached, s
  let stream: AbortController | null = null;
  let surface: SurfaceFrame | null = null;
  const states = new Map<string, InstrumentState>();
  let haveScene = false;

  function setDuration(d: number): void {
    duration = d;
    seek.max = String(duration);
    plot.setDuration(duration);
  }

  /** Asks the server for the recording's duration: as each stream starts and
   * ends, since the page may have opened while the server was away, and a
   * recording still being made grows. */
  function refreshDuration(): void {
    void recordings
      .listRecordings({}, { signal })
      .then((r) => {
        const d = r.recordings.find((x) => x.file === file)?.durationS;
        if (d !== undefined) setDuration(Math.max(d, at));
      })
      .catch((e) => {
        if (!signal.aborted) notice(`listing recordings: ${failure(e).text}`);
      });
  }

  // One listener for the page's signal, whatever the number of streams started.
  signal.addEventListener("abort", () => stream?.abort());

  /** Plays from `from`; or, `still`, shows the frame at `from` (the surface, the
   * instruments, the gauges and the time) and ends the stream: a seek while
   * paused stays paused. */
  function start(from: number, still = false): void {
    stream?.abort();
    const mine = new AbortController();
    stream = mine;
    page.dataset.state = still ? "paused" : "playing";
    // The time of the stream's first frame: where a seek landed.
    page.dataset.startedAt = "";
    setConnection("connecting", still ? "seeking" : "");
    /** Still: the tick of the frame shown, and the instruments whose state at
     * that tick has come (the server sends the tick at the offset at once, its
     * surface first; anything of a later tick means it is all there). */
    let stillTick: bigint | null = null;
    let names: string[] = [];
    const stillStates = new Set<string>();
    const shown = () => {
      if (mine !== stream) return;
      mine.abort();
      stream = null;
      setConnection("idle", "paused");
    };
    void (async () => {
      // A lost connection (the server restarting, say) is retried as the live
      // view does, from the time reached.
      for (let attempt = 0; ; attempt++) {
        try {
          const messages = recordings.replay(
            {
              file,
              speed: Number(speed.value),
              startOffsetS: from,
              mode: resim.checked ? ReplayMode.RESIMULATE : ReplayMode.RECORDED,
            },
            { signal: mine.signal },
          );
          for await (const m of messages) {
            const k = m.kind;
            if (k.case === "scene") {
              if (!haveScene) view.setScene(k.value);
              names = k.value.instruments.map((i) => i.name);
              gauges.set(names);
              haveScene = true;
              attempt = 0;
              // Playing again: what went wrong before is over.
              delete page.dataset.error;
              notice(null);
              refreshDuration();
              if (still) continue;
              page.dataset.state = "playing";
              setConnection("live");
            } else if (k.case === "surfaceFrame") {
              if (still) {
                if (stillTick !== null) return shown();
                stillTick = k.value.tick;
              }
              surface = k.value;
              at = k.value.simTimeS;
              // Past a duration listed while the recording was shorter.
              if (at > duration) setDuration(at);
              if (!page.dataset.startedAt) page.dataset.startedAt = at.toFixed(4);
            } else if (k.case === "instrumentState") {
              if (still && stillTick !== null && k.value.tick !== stillTick) return shown();
              states.set(k.value.instrument, k.value);
              plot.add(k.value.instrument, k.value.simTimeS, k.value.force?.magnitudeN ?? 0);
              if (still && stillTick !== null) {
                stillStates.add(k.value.instrument);
                if (names.every((n) => stillStates.has(n))) return shown();
              }
            }
          }
          // A seek while paused to the recording's end: its last frame is shown.
          if (still) return shown();
          if (mine === stream) {
            stream = null;
            page.dataset.state = "ended";
            setConnection("ended", "the recording played to its end");
            refreshDuration();
          }
          return;
        } catch (e) {
          if (mine.signal.aborted) return;
          const f = failure(e);
          if (f.code === Code.OutOfRange && mine === stream) {
            // A recording still being written, played to where it stood when
            // the replay began (the text says so): paused there, so that play
            // goes on from it with what has been recorded since.
            stream = null;
            page.dataset.state = "paused";
            setConnection("idle", f.text);
            refreshDuration();
            return;
          }
          page.dataset.error = f.text;
          const slot = f.code === Code.ResourceExhausted && attempt < SLOT_ATTEMPTS - 1;
          if (!f.retry && !slot) {
            page.dataset.state = "error";
            setConnection("error", f.text);
            notice(`replay: ${f.text}`);
            return;
          }
          // From the time reached, if this stream reached any (still: the
          // frame sought, whose surface may have come without its states).
          if (page.dataset.startedAt && !still) from = at;
          const wait = backoff(attempt);
          const why = slot ? "waiting for a replay slot" : f.text;
          setConnection("reconnecting", `${why}; again in ${(wait / 1000).toFixed(1)} s`);
          notice(`replay: ${why}; trying again in ${(wait / 1000).toFixed(1)} s`);
          await sleep(wait, mine.signal);
          if (mine.signal.aborted) return;
        }
      }
    })();
  }

  /** Nothing plays: paused, or played to the end. A seek shows the frame
   * sought and stays so; a speed changed is kept for the next play. */
  const standing = () => page.dataset.state === "paused" || page.dataset.state === "ended";
  // Played to the end (and not sought since), play starts again from the
  // beginning, as a media player does: playing on from the end would end at
  // once. After a seek (the end's included) it plays from the time sought.
  play.addEventListener("click", () => start(page.dataset.state === "ended" || (at >= duration && duration > 0) ? 0 : at));
  pause.addEventListener("click", () => {
    stream?.abort();
    stream = null;
    page.dataset.state = "paused";
    setConnection("idle", "paused");
  });
  const restart = () => {
    if (standing()) return;
    if (stream) start(at);
  };
  speed.addEventListener("change", restart);
  // Paused, the frame shown is drawn again as the mode chosen makes it; ended,
  // the mode is kept for the next play, as the speed is.
  resim.addEventListener("change", () => (page.dataset.state === "paused" ? start(at, true) : restart()));
  /** The user holds the seek bar: the frame loop leaves its value alone until
   * they let go. Not its focus, which stays after a click and would stop the
   * bar following the playback. */
  let seeking = false;
  seek.addEventListener("pointerdown", () => (seeking = true));
  for (const end of ["pointerup", "pointercancel"]) window.addEventListener(end, () => (seeking = false), { signal });
  seek.addEventListener("change", () => {
    seeking = false;
    at = Number(seek.value);
    plot.clearAfter(at);
    // Paused or ended, the frame at the time sought is shown and the replay
    // stays paused.
    start(at, standing());
  });

  let shownAt = -Infinity;

  function frame(now: number): void {
    if (signal.aborted) return;
    requestAnimationFrame(frame);
    if (surface) {
      view.setSurface(surface.positions);
      surface = null;
    }
    for (const s of states.values()) {
      view.setInstrument(s);
      gauges.update(s, false);
    }
    states.clear();
    view.draw();
    // The page's text, a few times a second: each write costs a layout.
    if (now - shownAt < TEXT_MS) return;
    shownAt = now;
    gauges.show((name) => view.heldDrawn(name));
    if (!seeking) seek.value = String(at);
    time.textContent = `${at.toFixed(2)} / ${duration.toFixed(2)} s`;
    page.dataset.time = at.toFixed(3);
    page.dataset.drawn = String(view.drawn);
    plot.draw(at);
  }
  requestAnimationFrame(frame);
  refreshDuration();
  start(0);
}

// The sessions page: the scenes, the live sessions (scene, stations, who holds
// which instrument, tick rate, missed deadlines, recording), creating and closing
// sessions, evicting a station, joining as a station or observing, and the
// recordings with a replay link. Refreshed every two seconds; a failure is said
// and retried.
import { Code, failure, recordings, scenes, sessions } from "./api";
import { MAX_DRIVEN } from "./live";
import type { SessionInfo } from "./gen/laparo/v1/session_pb";
import type { RecordingInfo } from "./gen/laparo/v1/recording_pb";
import { RecordingState } from "./gen/laparo/v1/recording_pb";
import type { SceneSummary } from "./gen/laparo/v1/scene_pb";
import { backoff, clearNotice, el, notice, setConnection, sleep } from "./status";

const REFRESH_MS = 2000;

export function sessionsPage(root: HTMLElement, signal: AbortSignal): void {
  const sceneTable = el("table", { id: "scenes" });
  const sessionTable = el("table", { id: "sessions" });
  const recordingTable = el("table", { id: "recordings" });
  const sceneSelect = el("select", { id: "new-scene" });
  // Indeterminate until the user ticks or clears it: the session is then
  // recorded as its scene declares ([recording] enabled), the request leaving
  // `record` unset; once changed, the box decides.
  const record = el("input", { id: "new-record", type: "checkbox" });
  record.indeterminate = true;
  const create = el("button", { id: "create", type: "button" }, "create session");
  root.replaceChildren(
    el("section", {}, el("h2", {}, "scenes"), sceneTable),
    el("section", {}, el("h2", {}, "sessions"), el("p", { class: "controls" }, sceneSelect, el("label", { title: "as the scene declares until ticked or cleared" }, record, " record"), create), sessionTable),
    el("section", {}, el("h2", {}, "recordings"), recordingTable),
  );
  let known: SceneSummary[] = [];
  create.addEventListener("click", async () => {
    try {
      const s = await sessions.createSession({ scene: sceneSelect.value, record: record.indeterminate ? undefined : record.checked }, { signal });
      location.hash = `#/live/${encodeURIComponent(s.sessionId)}?drive=${encodeURIComponent(known.find((k) => k.name === s.scene)?.instruments[0] ?? "")}`;
    } catch (e) {
      notice(`creating a session: ${failure(e).text}`);
    }
  });

  async function refresh(): Promise<void> {
    const [sc, ss, rs] = await Promise.all([
      scenes.listScenes({}, { signal }),
      sessions.listSessions({}, { signal }),
      recordings.listRecordings({}, { signal }).catch((e) => {
        // A server without recordings answers FAILED_PRECONDITION: no list.
        if (failure(e).code === 9) return { recordings: [] as RecordingInfo[] };
        throw e;
      }),
    ]);
    known = sc.scenes;
    renderScenes(sc.scenes, sc.unavailable.map((u) => `${u.name || u.file}: ${u.error}`));
    renderSessions(ss.sessions);
    renderRecordings(rs.recordings);
  }

  /** The scenes as last rendered: the same again is not rebuilt (the select
   * would lose its focus, and its list close under the user's pointer). */
  let scenesShown = "";

  function renderScenes(list: SceneSummary[], problems: string[]): void {
    const rows = list.map((s) => [
      s.name,
      s.description,
      String(s.vertexCount),
      String(s.tetrahedronCount),
      String(s.surfaceTriangleCount),
      `${s.mechanicsRateHz} Hz`,
      s.integrator,
      s.instruments.join(", "),
    ]);
    const shown = JSON.stringify([rows, problems]);
    if (shown === scenesShown) return;
    scenesShown = shown;
    sceneTable.replaceChildren(
      el("tr", {}, ...["scene", "description", "vertices", "tetrahedra", "surface triangles", "rate", "integrator", "instruments"].map((h) => el("th", {}, h))),
      ...rows.map((cells) => el("tr", { "data-scene": cells[0] }, ...cells.map((c) => el("td", {}, c)))),
      ...problems.map((p) => el("tr", {}, el("td", { colspan: "8" }, `unavailable: ${p}`))),
    );
    const current = sceneSelect.value;
    sceneSelect.replaceChildren(...list.map((s) => el("option", { value: s.name }, s.name)));
    if (list.some((s) => s.name === current)) sceneSelect.value = current;
  }

  const sessionHeader = el("tr", {}, ...["session", "scene", "stations", "instruments", "tick", "tick p50/p99", "missed", "observers", "recording", ""].map((h) => el("th", {}, h)));

  function renderSessions(list: SessionInfo[]): void {
    syncRows(
      sessionTable,
      sessionHeader,
      list.map((s) => {
        const instruments = s.instruments.map((i) => `${i.instrument}: ${i.stationId !== undefined ? `station ${i.stationId}` : "free"}`);
        const recording = s.recordingError ? `error: ${s.recordingError}` : s.recordingFile ? `recording ${s.recordingFile}` : "not recorded";
        return {
          key: s.sessionId,
          // The stations' cell and the links are made of these.
          shape: JSON.stringify([s.scene, s.stations.map((st) => [String(st.stationId), st.clientName, st.instruments]), s.instruments.map((i) => i.instrument)]),
          texts: [
            s.sessionId,
            s.scene,
            null,
            instruments.join("; "),
            `${s.tick} (${s.simTimeS.toFixed(1)} s)`,
            `${s.tickTimeP50Ms.toFixed(2)} / ${s.tickTimeP99Ms.toFixed(2)} ms`,
            String(s.missedDeadlines),
            String(s.observerCount),
            recording,
            null,
          ],
          build: () => sessionRow(s),
        };
      }),
    );
  }

  /** A session's row: its texts are written by syncRows. */
  function sessionRow(s: SessionInfo): HTMLTableRowElement {
    const links = el(
      "td",
      {},
      el("a", { href: `#/live/${encodeURIComponent(s.sessionId)}`, class: "observe" }, "observe"),
      ...s.instruments.map((i) => el("a", { href: `#/live/${encodeURIComponent(s.sessionId)}?drive=${encodeURIComponent(i.instrument)}`, class: "drive", style: "margin-left:0.5rem" }, `drive ${i.instrument}`)),
      // One page drives two instruments (live.ts, MAX_DRIVEN): the first two.
      s.instruments.length > 1
        ? el(
            "a",
            { href: `#/live/${encodeURIComponent(s.sessionId)}?drive=${s.instruments.slice(0, MAX_DRIVEN).map((i) => encodeURIComponent(i.instrument)).join(",")}`, class: "drive-both", style: "margin-left:0.5rem" },
            s.instruments.length > MAX_DRIVEN ? `drive ${s.instruments.slice(0, MAX_DRIVEN).map((i) => i.instrument).join(" + ")}` : "drive both",
          )
        : "",
    );
    const close = el("button", { type: "button", class: "close" }, "close");
    close.addEventListener("click", async () => {
      try {
        await sessions.closeSession({ sessionId: s.sessionId, reason: "closed from the console" }, { signal });
        await refresh();
      } catch (e) {
        notice(`closing ${s.sessionId}: ${failure(e).text}`);
      }
    });
    links.append(" ", close);
    // Each station, with a button to evict it (an instructor's call): its
    // page is told by whom and does not join again by itself.
    const stations = el("td", {});
    for (const st of s.stations) {
      const evict = el("button", { type: "button", class: "evict", "data-station": String(st.stationId) }, "evict");
      evict.addEventListener("click", async () => {
        try {
          await sessions.evictStation({ sessionId: s.sessionId, stationId: st.stationId, reason: "evicted from the console" }, { signal });
          await refresh();
        } catch (e) {
          notice(`evicting station ${st.stationId} of ${s.sessionId}: ${failure(e).text}`);
        }
      });
      if (stations.childElementCount > 0) stations.append("; ");
      stations.append(`${st.stationId} ${st.clientName} (${st.instruments.join(", ") || "watching"}) `, evict);
    }
    if (s.stations.length === 0) stations.append("none");
    return el("tr", { "data-session": s.sessionId }, el("td"), el("td"), stations, el("td"), el("td"), el("td"), el("td"), el("td"), el("td"), links);
  }

  const recordingHeader = el("tr", {}, ...["file", "session", "scene", "duration", "size", "state", ""].map((h) => el("th", {}, h)));

  function renderRecordings(list: RecordingInfo[]): void {
    syncRows(
      recordingTable,
      recordingHeader,
      list.map((r) => ({
        key: r.file,
        // An unfinished file, or one whose recorder failed, gets no replay link
        // (Replay refuses it until it is recovered); in progress, it has one
        // (instructors may replay it).
        shape: `${r.file} ${r.state} ${r.failure}`,
        texts: [
          r.file,
          r.sessionId,
          r.scene,
          `${r.durationS.toFixed(1)} s`,
          `${(Number(r.sizeBytes) / 1024).toFixed(0)} KiB`,
          RecordingState[r.state]?.replace("RECORDING_STATE_", "").toLowerCase() ?? "",
          null,
        ],
        build: () =>
          el(
            "tr",
            { "data-recording": r.file },
            ...Array.from({ length: 6 }, () => el("td")),
            el(
              "td",
              {},
              r.state === RecordingState.UNFINISHED
                ? el("span", { class: "unfinished" }, "unfinished: recover with `laparo recordings recover`")
                : r.state === RecordingState.FAILED
                  ? el(
                      "span",
                      { class: "unfinished" },
                      `its recorder failed (${r.failure}): recover what was written with \`laparo recordings recover\``,
                    )
                  : el("a", { href: `#/replay/${encodeURIComponent(r.file)}`, class: "replay" }, "replay"),
            ),
          ),
      })),
    );
  }

  void (async () => {
    /** The refresh's own notice (the connection lost), the only one it clears:
     * an action's error stays until the user reads it. */
    let lost: string | null = null;
    for (let attempt = 0; !signal.aborted; ) {
      try {
        await refresh();
        attempt = 0;
        setConnection("live");
        if (lost !== null) clearNotice(lost);
        lost = null;
        await sleep(REFRESH_MS, signal);
      } catch (e) {
        if (signal.aborted) return;
        const f = failure(e);
        if (f.auth || f.host) {
          setConnection("error", f.text);
          notice(f.code === Code.Unauthenticated ? `${f.text} — enter a token above` : f.text);
          document.body.dataset.error = f.text;
          return;
        }
        const wait = backoff(attempt++);
        setConnection("reconnecting", f.text);
        lost = `${f.text}; trying again in ${(wait / 1000).toFixed(1)} s`;
        notice(lost);
        await sleep(wait, signal);
      }
    }
  })();
}

/** A row of a table kept across refreshes by syncRows. */
interface Row {
  /** Tells the row among the others (a session's id, a recording's file). */
  key: string;
  /** What the row's links and buttons are made of: the row is built again when it changes. */
  shape: string;
  /** The text of each cell, written where it changed; null for a cell of links or buttons. */
  texts: (string | null)[];
  build: () => HTMLTableRowElement;
}

/** The shape each row was built for. */
const shapes = new WeakMap<HTMLTableRowElement, string>();

/** Shows `rows` in `table` under `header` without rebuilding what did not
 * change: a row of the same key and shape stays in the page, only its changed
 * texts rewritten, so a link or button in it keeps the keyboard focus across
 * the refreshes; a row is built anew only when its shape changed, and moved
 * only when the order did. */
function syncRows(table: HTMLTableElement, header: HTMLTableRowElement, rows: Row[]): void {
  const old = new Map<string, HTMLTableRowElement>();
  for (const tr of table.querySelectorAll<HTMLTableRowElement>(":scope > tr[data-key]")) old.set(tr.dataset.key!, tr);
  if (table.firstElementChild !== header) table.prepend(header);
  let previous: Element = header;
  for (const r of rows) {
    let tr = old.get(r.key);
    old.delete(r.key);
    let focused: string | null = null;
    if (!tr || shapes.get(tr) !== r.shape) {
      // A row rebuilt (its stations changed, say) gives the focus it held to
      // the same control of the new row: the same link, or the same button,
      // once the row is in the page (a detached element takes no focus).
      focused = tr?.contains(document.activeElement) ? controlKey(document.activeElement) : null;
      tr?.remove();
      tr = r.build();
      tr.dataset.key = r.key;
      shapes.set(tr, r.shape);
    }
    r.texts.forEach((text, i) => {
      const cell = tr.cells[i];
      if (text !== null && cell && cell.textContent !== text) cell.textContent = text;
    });
    if (previous.nextElementSibling !== tr) previous.after(tr);
    if (focused) [...tr.querySelectorAll<HTMLElement>("a, button")].find((e) => controlKey(e) === focused)?.focus();
    previous = tr;
  }
  for (const tr of old.values()) tr.remove();
}

/** What tells a row's link or button from the others of the row: its class,
 * its address, its station, its text. */
function controlKey(e: Element | null): string {
  if (!e) return "";
  return [e.tagName, e.className, e.getAttribute("href") ?? "", (e as HTMLElement).dataset.station ?? "", e.textContent ?? ""].join("\u0000");
}

// The sessions page: the scenes, the live sessions (scene, stations, who holds
// which instrument, tick rate, missed deadlines, recording), creating and closing
// sessions, evicting a station, joining as a station or observing, and the recordings with a replay
// link. Refreshed every two seconds; a failure is said and retried.
import { Code, failure, recordings, scenes, sessions } from "./api";
import type { SessionInfo } from "./gen/laparo/v1/session_pb";
import type { RecordingInfo } from "./gen/laparo/v1/recording_pb";
import { RecordingState } from "./gen/laparo/v1/recording_pb";
import type { SceneSummary } from "./gen/laparo/v1/scene_pb";
import { backoff, el, notice, setConnection, sleep } from "./status";

const REFRESH_MS = 2000;

export function sessionsPage(root: HTMLElement, signal: AbortSignal): void {
  const sceneTable = el("table", { id: "scenes" });
  const sessionTable = el("table", { id: "sessions" });
  const recordingTable = el("table", { id: "recordings" });
  const sceneSelect = el("select", { id: "new-scene" });
  const record = el("input", { id: "new-record", type: "checkbox" });
  const create = el("button", { id: "create", type: "button" }, "create session");
  root.replaceChildren(
    el("section", {}, el("h2", {}, "scenes"), sceneTable),
    el("section", {}, el("h2", {}, "sessions"), el("p", { class: "controls" }, sceneSelect, el("label", {}, record, " record"), create), sessionTable),
    el("section", {}, el("h2", {}, "recordings"), recordingTable),
  );
  let known: SceneSummary[] = [];
  create.addEventListener("click", async () => {
    try {
      const s = await sessions.createSession({ scene: sceneSelect.value, record: record.checked }, { signal });
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

  function renderScenes(list: SceneSummary[], problems: string[]): void {
    sceneTable.replaceChildren(
      el("tr", {}, ...["scene", "description", "vertices", "tetrahedra", "surface triangles", "rate", "integrator", "instruments"].map((h) => el("th", {}, h))),
      ...list.map((s) =>
        el(
          "tr",
          { "data-scene": s.name },
          el("td", {}, s.name),
          el("td", {}, s.description),
          el("td", {}, String(s.vertexCount)),
          el("td", {}, String(s.tetrahedronCount)),
          el("td", {}, String(s.surfaceTriangleCount)),
          el("td", {}, `${s.mechanicsRateHz} Hz`),
          el("td", {}, s.integrator),
          el("td", {}, s.instruments.join(", ")),
        ),
      ),
      ...problems.map((p) => el("tr", {}, el("td", { colspan: "8" }, `unavailable: ${p}`))),
    );
    const current = sceneSelect.value;
    sceneSelect.replaceChildren(...list.map((s) => el("option", { value: s.name }, s.name)));
    if (list.some((s) => s.name === current)) sceneSelect.value = current;
  }

  function renderSessions(list: SessionInfo[]): void {
    sessionTable.replaceChildren(
      el("tr", {}, ...["session", "scene", "stations", "instruments", "tick", "tick p50/p99", "missed", "observers", "recording", ""].map((h) => el("th", {}, h))),
      ...list.map((s) => {
        const instruments = s.instruments.map((i) => `${i.instrument}: ${i.stationId !== undefined ? `station ${i.stationId}` : "free"}`);
        const links = el(
          "td",
          {},
          el("a", { href: `#/live/${encodeURIComponent(s.sessionId)}`, class: "observe" }, "observe"),
          ...s.instruments.map((i) => el("a", { href: `#/live/${encodeURIComponent(s.sessionId)}?drive=${encodeURIComponent(i.instrument)}`, class: "drive", style: "margin-left:0.5rem" }, `drive ${i.instrument}`)),
          s.instruments.length > 1
            ? el("a", { href: `#/live/${encodeURIComponent(s.sessionId)}?drive=${s.instruments.map((i) => encodeURIComponent(i.instrument)).join(",")}`, style: "margin-left:0.5rem" }, "drive all")
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
        const recording = s.recordingError ? `error: ${s.recordingError}` : s.recordingFile ? `recording ${s.recordingFile}` : "not recorded";
        return el(
          "tr",
          { "data-session": s.sessionId },
          el("td", {}, s.sessionId),
          el("td", {}, s.scene),
          stations,
          el("td", {}, instruments.join("; ")),
          el("td", {}, `${s.tick} (${s.simTimeS.toFixed(1)} s)`),
          el("td", {}, `${s.tickTimeP50Ms.toFixed(2)} / ${s.tickTimeP99Ms.toFixed(2)} ms`),
          el("td", {}, String(s.missedDeadlines)),
          el("td", {}, String(s.observerCount)),
          el("td", {}, recording),
          links,
        );
      }),
    );
  }

  function renderRecordings(list: RecordingInfo[]): void {
    recordingTable.replaceChildren(
      el("tr", {}, ...["file", "session", "scene", "duration", "size", "state", ""].map((h) => el("th", {}, h))),
      ...list.map((r) =>
        el(
          "tr",
          { "data-recording": r.file },
          el("td", {}, r.file),
          el("td", {}, r.sessionId),
          el("td", {}, r.scene),
          el("td", {}, `${r.durationS.toFixed(1)} s`),
          el("td", {}, `${(Number(r.sizeBytes) / 1024).toFixed(0)} KiB`),
          el("td", {}, RecordingState[r.state]?.replace("RECORDING_STATE_", "").toLowerCase() ?? ""),
          el("td", {}, el("a", { href: `#/replay/${encodeURIComponent(r.file)}`, class: "replay" }, "replay")),
        ),
      ),
    );
  }

  void (async () => {
    for (let attempt = 0; !signal.aborted; ) {
      try {
        await refresh();
        attempt = 0;
        setConnection("live");
        notice(null);
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
        notice(`${f.text}; trying again in ${(wait / 1000).toFixed(1)} s`);
        await sleep(wait, signal);
      }
    }
  })();
}

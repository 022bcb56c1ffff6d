// A force gauge per instrument: |F| as a bar (full at GAUGE_FULL_N) and a number,
// its holder and contact; data-force-n carries the value for the browser tests.
// data-held-count is the state's held_vertex_count, data-held-drawn the held
// vertices the 3D view draws. `update` keeps the newest state; `show` writes the page (a few times a second:
// the text and the bar's width each cost a layout).
import type { InstrumentState } from "../gen/laparo/v1/frame_pb";
import { ContactState } from "../gen/laparo/v1/frame_pb";
import { el } from "../status";

/** |F| that fills the gauge, N: a firm press on the default liver. */
const GAUGE_FULL_N = 5;

export class Gauges {
  readonly root = el("div", { id: "gauges" });
  private rows = new Map<string, { row: HTMLElement; bar: HTMLElement; text: HTMLElement; state: InstrumentState | null; mine: boolean }>();

  set(names: string[]): void {
    this.root.replaceChildren();
    this.rows.clear();
    for (const name of names) {
      const bar = el("div");
      const text = el("span", {}, "free");
      const row = el("div", { class: "instrument", "data-instrument": name, "data-force-n": "0" }, el("strong", { title: name }, name), " ", text, el("div", { class: "gauge" }, bar));
      this.root.append(row);
      this.rows.set(name, { row, bar, text, state: null, mine: false });
    }
  }

  update(s: InstrumentState, mine: boolean): void {
    const r = this.rows.get(s.instrument);
    if (!r) return;
    r.state = s;
    r.mine = mine;
  }

  /** Writes the newest states to the page, with the held vertices the view
   * draws for each instrument (data-held-drawn, beside data-held-count). */
  show(heldDrawn: (instrument: string) => number): void {
    for (const [name, r] of this.rows) {
      if (r.state) this.write(r, r.state, r.mine);
      r.state = null;
      r.row.dataset.heldDrawn = String(heldDrawn(name));
    }
  }

  private write(r: { row: HTMLElement; bar: HTMLElement; text: HTMLElement }, s: InstrumentState, mine: boolean): void {
    const f = s.force?.magnitudeN ?? 0;
    r.row.dataset.forceN = f.toFixed(4);
    r.row.dataset.held = s.stationId !== undefined ? String(s.stationId) : "";
    r.row.dataset.heldCount = String(s.heldVertexCount);
    r.row.dataset.tip = s.pose?.tip ? `${s.pose.tip.x.toFixed(4)},${s.pose.tip.y.toFixed(4)},${s.pose.tip.z.toFixed(4)}` : "";
    r.bar.style.width = `${Math.min(100, (100 * f) / GAUGE_FULL_N)}%`;
    const holder = s.stationId !== undefined ? `station ${s.stationId}${mine ? " (you)" : ""}` : "free";
    r.text.textContent = `${holder} · ${ContactState[s.contact]?.replace("CONTACT_STATE_", "").toLowerCase() ?? ""} · ${f.toFixed(2)} N · held ${s.heldVertexCount}`;
  }
}

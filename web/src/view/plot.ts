// |force| over simulated time, one line per instrument, drawn on a 2D canvas;
// the replay's current time as a vertical line.
const COLORS = ["#d9534f", "#337ab7", "#5cb85c", "#f0ad4e"];

/** The colour of the k-th instrument: the four above, then hues a golden
 * angle apart, so that no two of any number of instruments share one. */
export function color(k: number): string {
  if (k < COLORS.length) return COLORS[k];
  const hue = (280 + (k - COLORS.length) * 137.508) % 360;
  return `hsl(${hue.toFixed(1)}, 65%, ${k % 2 ? 38 : 48}%)`;
}

export class ForcePlot {
  readonly canvas = Object.assign(document.createElement("canvas"), { className: "plot", id: "force-plot" });
  private series = new Map<string, { t: number[]; f: number[] }>();
  private duration = 0;
  private dirty = true;

  setDuration(s: number): void {
    this.duration = s;
    this.dirty = true;
  }

  add(instrument: string, t: number, f: number): void {
    let s = this.series.get(instrument);
    if (!s) this.series.set(instrument, (s = { t: [], f: [] }));
    // Out of order (after a seek back): start the curve again from there.
    if (s.t.length && t < s.t[s.t.length - 1]) this.clearAfter(t);
    s.t.push(t);
    s.f.push(f);
    this.dirty = true;
  }

  clearAfter(t: number): void {
    for (const s of this.series.values()) {
      const k = s.t.findIndex((x) => x > t);
      if (k >= 0) {
        s.t.length = k;
        s.f.length = k;
      }
    }
    this.dirty = true;
  }

  draw(now: number): void {
    if (!this.dirty && this.canvas.dataset.now === now.toFixed(2)) return;
    this.dirty = false;
    this.canvas.dataset.now = now.toFixed(2);
    const c = this.canvas;
    const w = (c.width = c.clientWidth || 300);
    const h = (c.height = c.clientHeight || 160);
    const g = c.getContext("2d")!;
    g.clearRect(0, 0, w, h);
    let fmax = 0.5;
    let tmax = Math.max(this.duration, 1e-3);
    for (const s of this.series.values()) {
      for (const f of s.f) fmax = Math.max(fmax, f);
      if (s.t.length) tmax = Math.max(tmax, s.t[s.t.length - 1]);
    }
    const x = (t: number) => 30 + ((w - 35) * t) / tmax;
    const y = (f: number) => h - 15 - ((h - 25) * f) / fmax;
    g.fillStyle = "#555";
    g.font = "10px sans-serif";
    g.fillText(`${fmax.toFixed(1)} N`, 2, 12);
    g.fillText(`${tmax.toFixed(0)} s`, w - 25, h - 2);
    let k = 0;
    // The legend: each name after the last, wrapped to a new line where it
    // would pass the canvas's right edge.
    let lx = 35;
    let ly = 12;
    for (const [name, s] of this.series) {
      g.strokeStyle = color(k);
      g.beginPath();
      for (let i = 0; i < s.t.length; i++) {
        if (i === 0) g.moveTo(x(s.t[i]), y(s.f[i]));
        else g.lineTo(x(s.t[i]), y(s.f[i]));
      }
      g.stroke();
      g.fillStyle = g.strokeStyle;
      // A name wider than the canvas is squeezed into it.
      const width = Math.min(g.measureText(name).width, w - 37);
      if (lx > 35 && lx + width > w - 2) {
        lx = 35;
        ly += 12;
      }
      g.fillText(name, lx, ly, width);
      lx += width + 10;
      k++;
    }
    g.strokeStyle = "#999";
    g.beginPath();
    g.moveTo(x(now), 0);
    g.lineTo(x(now), h);
    g.stroke();
  }
}

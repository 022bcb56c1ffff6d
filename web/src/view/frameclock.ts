// Main-thread time spent in the page's frame loop, for the measurements
// (web/tests/measure.mjs): the whole frame callback, and within it the time in
// three.js's render call (scene traversal and issuing the WebGL commands; the
// rasterising itself runs in the GPU process). Totals since the page opened, in
// ms, published as data- attributes of the page's root (no allocation per frame).
export class FrameClock {
  private frames = 0;
  private workMs = 0;
  private renderMs = 0;
  private t0 = 0;
  private r0 = 0;

  begin(): void {
    this.t0 = performance.now();
  }

  beginRender(): void {
    this.r0 = performance.now();
  }

  endRender(): void {
    this.renderMs += performance.now() - this.r0;
  }

  /** Ends a frame; every second or so writes the totals to `root`'s dataset. */
  end(root: HTMLElement): void {
    this.workMs += performance.now() - this.t0;
    this.frames++;
    if (this.frames % 30 === 0) this.publish(root);
  }

  publish(root: HTMLElement): void {
    root.dataset.loopFrames = String(this.frames);
    root.dataset.loopWorkMs = this.workMs.toFixed(3);
    root.dataset.loopRenderMs = this.renderMs.toFixed(3);
  }
}

// What the console costs in headless chromium, per scene, for an observer of a
// fresh session: per animation frame, the renderer main thread's CPU time (the
// DevTools Performance domain's ThreadTime) and its tasks' wall time
// (TaskDuration: CPU time plus what the thread waited for, chiefly the
// compositor and the GPU process in Commit, which on a loaded machine dominate),
// and the page's own frame loop (web/src/view/frameclock.ts: all of the frame
// callback, and the three.js render call within it); JS heap growth, bytes per
// second an observer receives, and the time from opening the page to the first
// drawn frame. Prints a markdown table.
// Usage: node measure.mjs URL [TOKEN] [SECONDS] [SCENE...]
//   (default: 30 s, the scenes `default` and `liver-20k` where the server has them)
import { createSession, launch } from "./browser.mjs";

const [url, token = "", seconds = "30", ...wanted] = process.argv.slice(2);
const scenes = wanted.length ? wanted : ["default", "liver-20k"];
const { context, close } = await launch();
await context.addInitScript((t) => t && sessionStorage.setItem("laparo.token", t), token);
// Animation frames, counted apart from the page's own loop.
await context.addInitScript(() => {
  window.__animationFrames = 0;
  const count = () => {
    window.__animationFrames++;
    requestAnimationFrame(count);
  };
  requestAnimationFrame(count);
});

/** The page's own frame-loop totals (web/src/view/frameclock.ts). */
async function loop(page) {
  return page.$eval("#live", (e) => ({
    frames: Number(e.dataset.loopFrames ?? 0),
    work: Number(e.dataset.loopWorkMs ?? 0),
    render: Number(e.dataset.loopRenderMs ?? 0),
  }));
}

/** The Performance domain's metrics, after a full garbage collection (so that
 * the JS heap is what the page keeps, not what it has yet to collect). */
async function metrics(cdp) {
  await cdp.send("HeapProfiler.collectGarbage");
  const { metrics } = await cdp.send("Performance.getMetrics");
  return Object.fromEntries(metrics.map((m) => [m.name, m.value]));
}

console.log(
  "| scene | vertices | animation frames/s | frames/s drawn | main thread CPU ms/frame | main thread task wall ms/frame | frame loop ms/frame (of which render) | JS heap start → end MB | observer kB/s | first frame ms |",
);
console.log("|---|---|---|---|---|---|---|---|---|---|");
try {
  const lobby = await context.newPage();
  await lobby.goto(url);
  await lobby.waitForSelector("#scenes tr[data-scene]", { timeout: 30_000 });
  const listed = await lobby.$$eval("#scenes tr[data-scene]", (rows) => rows.map((r) => r.dataset.scene));
  for (const scene of scenes) {
    if (!listed.includes(scene)) {
      console.log(`| ${scene} | not served | | | | | | | | |`);
      continue;
    }
    await lobby.goto(`${url}#/`);
    const session = await createSession(lobby, url, scene);

    const page = await context.newPage();
    const cdp = await context.newCDPSession(page);
    await cdp.send("Performance.enable");
    await cdp.send("Network.enable");
    let bytes = 0;
    const observeRequests = new Set();
    cdp.on("Network.requestWillBeSent", (e) => {
      if (e.request.url.includes("laparo.v1.Observe/Observe")) observeRequests.add(e.requestId);
    });
    cdp.on("Network.dataReceived", (e) => {
      if (observeRequests.has(e.requestId)) bytes += e.encodedDataLength || e.dataLength;
    });
    await page.goto(`${url}#/live/${encodeURIComponent(session)}`);
    await page.waitForFunction(() => document.querySelector("#live")?.dataset.firstFrameMs, null, { timeout: 60_000 });
    const firstFrame = await page.$eval("#live", (e) => Number(e.dataset.firstFrameMs));
    await page.waitForTimeout(2000);
    const m0 = await metrics(cdp);
    const a0 = await page.evaluate(() => window.__animationFrames);
    const l0 = await loop(page);
    const d0 = await page.$eval("#live", (e) => Number(e.dataset.drawn));
    const b0 = bytes;
    const t0 = Date.now();
    await page.waitForTimeout(Number(seconds) * 1000);
    const m1 = await metrics(cdp);
    const a1 = await page.evaluate(() => window.__animationFrames);
    const l1 = await loop(page);
    const d1 = await page.$eval("#live", (e) => Number(e.dataset.drawn));
    const elapsed = (Date.now() - t0) / 1000;
    const frames = d1 - d0;
    const animationFrames = Math.max(1, a1 - a0);
    const cpu = ((m1.ThreadTime - m0.ThreadTime) * 1000) / animationFrames;
    const wall = ((m1.TaskDuration - m0.TaskDuration) * 1000) / animationFrames;
    const loopFrames = l1.frames - l0.frames;
    const work = (l1.work - l0.work) / loopFrames;
    const render = (l1.render - l0.render) / loopFrames;
    const frameLoop = loopFrames > 0 ? `${work.toFixed(2)} (${render.toFixed(2)})` : "–";
    console.log(
      `| ${scene} | ${await vertexCount(lobby, scene)} | ${(animationFrames / elapsed).toFixed(1)} | ${(frames / elapsed).toFixed(1)} | ${cpu.toFixed(2)} | ${wall.toFixed(2)} | ${frameLoop} | ${(m0.JSHeapUsedSize / 1e6).toFixed(1)} → ${(m1.JSHeapUsedSize / 1e6).toFixed(1)} | ${((bytes - b0) / 1000 / elapsed).toFixed(0)} | ${firstFrame.toFixed(0)} |`,
    );
    await page.close();
  }
} finally {
  await close();
}

async function vertexCount(lobby, scene) {
  return lobby.$eval(`#scenes tr[data-scene="${scene}"]`, (r) => r.children[2]?.textContent ?? "");
}

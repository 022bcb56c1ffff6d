// Where the console's main thread spends its time in a live view: a DevTools
// trace of SECONDS of an observed session, summed by what the renderer's main
// thread ran (top-level tasks, and the work inside them: script, style, layout,
// paint, garbage collection, the frame loop), per animation frame.
// Usage: node profile.mjs URL [TOKEN] [SECONDS] [SCENE]
import { createSession, launch } from "./browser.mjs";

const [url, token = "", seconds = "5", scene = "default"] = process.argv.slice(2);
const { context, close } = await launch();
await context.addInitScript((t) => t && sessionStorage.setItem("laparo.token", t), token);
try {
  const lobby = await context.newPage();
  await lobby.goto(url);
  const session = await createSession(lobby, url, scene);

  const page = await context.newPage();
  await page.goto(`${url}#/live/${encodeURIComponent(session)}`);
  await page.waitForFunction(() => document.querySelector("#live")?.dataset.firstFrameMs, null, { timeout: 60_000 });
  await page.waitForTimeout(2000);
  const cdp = await context.newCDPSession(page);
  const events = [];
  cdp.on("Tracing.dataCollected", (e) => events.push(...e.value));
  const done = new Promise((resolve) => cdp.once("Tracing.tracingComplete", resolve));
  await cdp.send("Tracing.start", {
    categories: "devtools.timeline,v8,v8.execute,disabled-by-default-devtools.timeline,blink.user_timing",
    transferMode: "ReportEvents",
  });
  await page.waitForTimeout(Number(seconds) * 1000);
  await cdp.send("Tracing.end");
  await done;

  // The renderer's main thread: the thread named CrRendererMain of the page's process.
  const names = new Map();
  for (const e of events) {
    if (e.name === "thread_name") names.set(`${e.pid}:${e.tid}`, e.args.name);
  }
  const main = new Set([...names].filter(([, n]) => n === "CrRendererMain").map(([k]) => k));
  // dur: wall time; tdur: the thread's CPU time (waiting, e.g. for the
  // compositor in Commit, is wall time without CPU time).
  const total = new Map();
  const add = (k, e) => {
    const t = total.get(k) ?? { wall: 0, cpu: 0 };
    t.wall += e.dur;
    t.cpu += e.tdur ?? 0;
    total.set(k, t);
  };
  let frames = 0;
  const busy = { wall: 0, cpu: 0 };
  for (const e of events) {
    if (!main.has(`${e.pid}:${e.tid}`) || e.ph !== "X" || !e.dur) continue;
    if (e.name === "RunTask") {
      busy.wall += e.dur;
      busy.cpu += e.tdur ?? 0;
    }
    if (e.name === "FireAnimationFrame") frames++;
    if (e.name !== "RunTask") add(e.name, e);
  }
  const perFrame = (us) => (us / 1000 / Math.max(1, frames)).toFixed(3);
  console.log(
    `${scene}: ${frames} animation frames in ${seconds} s; main thread per frame: busy ${perFrame(busy.wall)} ms wall, ${perFrame(busy.cpu)} ms CPU`,
  );
  console.log("| event (nested events counted in their parents too) | wall ms per frame | CPU ms per frame |");
  console.log("|---|---|---|");
  for (const [k, t] of [...total].sort((a, b) => b[1].wall - a[1].wall).slice(0, 20)) {
    console.log(`| ${k} | ${perFrame(t.wall)} | ${perFrame(t.cpu)} |`);
  }
} finally {
  await close();
}

// What the console costs in headless chromium, per scene: main-thread time per
// drawn frame (the DevTools Performance domain's TaskDuration over the frames
// drawn), JS heap growth, bytes per second an observer receives, and the time
// from opening the page to the first drawn frame. Prints a markdown table.
// Usage: node measure.mjs URL [TOKEN] [SECONDS] [SCENE...]
//   (default: 30 s, the scenes `default` and `liver-20k` where the server has them)
import { launch } from "./browser.mjs";

const [url, token = "", seconds = "30", ...wanted] = process.argv.slice(2);
const scenes = wanted.length ? wanted : ["default", "liver-20k"];
const { context, close } = await launch();
await context.addInitScript((t) => t && sessionStorage.setItem("laparo.token", t), token);

async function metrics(cdp) {
  const { metrics } = await cdp.send("Performance.getMetrics");
  return Object.fromEntries(metrics.map((m) => [m.name, m.value]));
}

console.log("| scene | vertices | frames/s drawn | main thread ms/frame | JS heap start → end MB | observer kB/s | first frame ms |");
console.log("|---|---|---|---|---|---|---|");
try {
  const lobby = await context.newPage();
  await lobby.goto(url);
  await lobby.waitForSelector("#scenes tr[data-scene]", { timeout: 30_000 });
  const listed = await lobby.$$eval("#scenes tr[data-scene]", (rows) => rows.map((r) => r.dataset.scene));
  for (const scene of scenes) {
    if (!listed.includes(scene)) {
      console.log(`| ${scene} | not served | | | | | |`);
      continue;
    }
    await lobby.goto(`${url}#/`);
    await lobby.waitForSelector(`#new-scene option[value="${scene}"]`, { state: "attached" });
    await lobby.selectOption("#new-scene", scene);
    await lobby.click("#create");
    await lobby.waitForSelector("#live[data-session]");
    const session = await lobby.$eval("#live", (e) => e.dataset.session);
    await lobby.goto(`${url}#/`);

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
    const d0 = await page.$eval("#live", (e) => Number(e.dataset.drawn));
    const b0 = bytes;
    const t0 = Date.now();
    await page.waitForTimeout(Number(seconds) * 1000);
    const m1 = await metrics(cdp);
    const d1 = await page.$eval("#live", (e) => Number(e.dataset.drawn));
    const elapsed = (Date.now() - t0) / 1000;
    const frames = d1 - d0;
    const ms = ((m1.TaskDuration - m0.TaskDuration) * 1000) / Math.max(1, frames);
    console.log(
      `| ${scene} | ${await vertexCount(lobby, scene)} | ${(frames / elapsed).toFixed(1)} | ${ms.toFixed(2)} | ${(m0.JSHeapUsedSize / 1e6).toFixed(1)} → ${(m1.JSHeapUsedSize / 1e6).toFixed(1)} | ${((bytes - b0) / 1000 / elapsed).toFixed(0)} | ${firstFrame.toFixed(0)} |`,
    );
    await page.close();
  }
} finally {
  await close();
}

async function vertexCount(lobby, scene) {
  return lobby.$eval(`#scenes tr[data-scene="${scene}"]`, (r) => r.children[2]?.textContent ?? "");
}

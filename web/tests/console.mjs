// The console's browser tests (run by tests/tests/console.rs against a real
// laparo-server with tokens): each step asserts one property of issue 12's
// "Must hold", reading the page's state from the DOM (data- attributes, text).
// Usage: node console.mjs URL INSTRUCTOR_TOKEN OUT_DIR
import { launch, watch } from "./browser.mjs";

const [url, token, out] = process.argv.slice(2);
const problems = [];
const T = 30_000;
let step = "start";

function check(cond, what) {
  if (!cond) throw new Error(`${step}: ${what}`);
}

async function useToken(page, t) {
  await page.fill("#token", t);
  await page.click("#token-form button");
}

/** Liver-coloured pixels (red well above green and blue) in the centre of the 3D view. */
async function liverPixels(page) {
  return page.evaluate(() => {
    const gl = document.querySelector("#viewport canvas");
    const c = document.createElement("canvas");
    c.width = gl.width;
    c.height = gl.height;
    const g = c.getContext("2d");
    g.drawImage(gl, 0, 0);
    const x0 = Math.floor(c.width * 0.4), y0 = Math.floor(c.height * 0.4);
    const w = Math.floor(c.width * 0.2), h = Math.floor(c.height * 0.2);
    const d = g.getImageData(x0, y0, w, h).data;
    let liver = 0;
    for (let i = 0; i < d.length; i += 4) {
      if (d[i] > 60 && d[i] > 1.4 * d[i + 1] && d[i] > 1.4 * d[i + 2]) liver++;
    }
    return liver / (w * h);
  });
}

const { context, close } = await launch();
let status = 0;
try {
  // The console lists the default scene.
  step = "sessions page";
  const driver = await context.newPage();
  watch(driver, "driver", problems);
  await driver.goto(url);
  await useToken(driver, token);
  await driver.waitForSelector('#scenes tr[data-scene="default"]', { timeout: T });
  console.log("ok default scene listed");

  // Create a session and drive its left instrument into the liver.
  step = "create and drive";
  await driver.check("#new-record");
  await driver.click("#create");
  await driver.waitForSelector('#live[data-mode="drive"]', { timeout: T });
  step = "driving: connected";
  await driver.waitForFunction(() => document.querySelector("#connection")?.dataset.state === "live", null, { timeout: T });
  step = "driving: drawn";
  await driver.waitForFunction(() => Number(document.querySelector("#live")?.dataset.drawn) > 0, null, { timeout: T });
  step = "driving: inserting";
  const sessionId = await driver.$eval("#live", (e) => e.dataset.session);
  const box = await driver.$eval("#viewport canvas", (e) => {
    const r = e.getBoundingClientRect();
    return { x: r.x + r.width / 2, y: r.y + r.height / 2 };
  });
  // A small pivot by dragging, then insertion with the wheel until the force shows.
  await driver.mouse.move(box.x, box.y);
  await driver.mouse.down();
  await driver.mouse.move(box.x + 5, box.y + 3, { steps: 3 });
  await driver.mouse.up();
  let force = 0;
  // Until the press is firm (0.3 N), so that the surface visibly gives way.
  for (let i = 0; i < 100 && force < 0.3; i++) {
    await driver.mouse.wheel(0, 100);
    await driver.waitForTimeout(60);
    force = await driver.$eval('#gauges [data-instrument="left"]', (e) => Number(e.dataset.forceN));
  }
  check(force > 0, `the left force gauge reads ${force} N after inserting`);
  step = "driving: surface moves";
  await driver.waitForFunction(() => Number(document.querySelector("#live")?.dataset.surfaceChangeMm) > 0.5, null, { timeout: T });
  const moved = await driver.$eval("#live", (e) => Number(e.dataset.surfaceChangeMm));
  console.log(`ok surface moved ${moved.toFixed(2)} mm, force ${force.toFixed(3)} N`);

  // The liver is drawn: liver-coloured pixels where the liver is.
  step = "screenshot";
  const fraction = await liverPixels(driver);
  await driver.screenshot({ path: `${out}/live.png` });
  check(fraction > 0.3, `only ${(fraction * 100).toFixed(0)}% of the view's centre is liver-coloured`);
  console.log(`ok liver drawn: ${(fraction * 100).toFixed(0)}% liver-coloured at the centre`);

  // A second browser context observing sees the same instrument.
  step = "observer";
  const other = await (await launch()).context;
  const observer = await other.newPage();
  watch(observer, "observer", problems);
  await observer.goto(url);
  await useToken(observer, token);
  await observer.goto(`${url}#/live/${encodeURIComponent(sessionId)}`);
  await observer.waitForFunction(() => document.querySelector('#gauges [data-instrument="left"]')?.dataset.held, null, { timeout: T });
  const seen = await observer.$eval('#gauges [data-instrument="left"]', (e) => ({ held: e.dataset.held, tip: e.dataset.tip }));
  const mine = await driver.$eval('#gauges [data-instrument="left"]', (e) => ({ held: e.dataset.held, tip: e.dataset.tip }));
  check(seen.held === mine.held, `the observer sees left held by ${seen.held}, the driver by ${mine.held}`);
  check(seen.tip === mine.tip, `the observer sees the tip at ${seen.tip}, the driver at ${mine.tip}`);
  console.log(`ok observer sees left held by station ${seen.held} at ${seen.tip}`);

  // Closing the session is said on both pages.
  step = "close";
  await driver.goto(`${url}#/`);
  await driver.waitForSelector(`#sessions tr[data-session="${sessionId}"] button.close`, { timeout: T });
  await driver.click(`#sessions tr[data-session="${sessionId}"] button.close`);
  step = "close: the session leaves the list";
  await driver.waitForSelector(`#sessions tr[data-session="${sessionId}"]`, { state: "detached", timeout: T });
  step = "close: the observer is told";
  await observer
    .waitForFunction(() => document.querySelector("#connection")?.dataset.state === "ended", null, { timeout: T })
    .catch(async (e) => {
      console.error(`observer: ${await observer.$eval("#connection", (e) => e.textContent)}; ${await observer.$eval("#notice", (e) => e.textContent)}`);
      throw e;
    });
  console.log(`ok observer told: ${await observer.$eval("#connection", (e) => e.textContent)}`);
  await other.close();

  // A replay plays the recording to its end.
  step = "replay";
  const row = await driver.waitForSelector(`#recordings tr[data-recording] >> text=${sessionId}`, { timeout: T });
  const file = await row.evaluate((e) => e.closest("tr").dataset.recording);
  await driver.goto(`${url}#/replay/${encodeURIComponent(file)}`);
  await driver.waitForFunction(() => Number(document.querySelector("#replay")?.dataset.drawn) > 0, null, { timeout: T });
  await driver.selectOption("#speed", "10");
  await driver.waitForFunction(() => document.querySelector("#replay")?.dataset.state === "ended", null, { timeout: 60_000 });
  await driver.screenshot({ path: `${out}/replay.png` });
  console.log(`ok replay of ${file} played to its end at ${await driver.$eval("#replay", (e) => e.dataset.time)} s`);

  // A wrong token is refused on the page.
  step = "wrong token";
  const stranger = await context.newPage();
  watch(stranger, "stranger", problems);
  // The browser logs the refused call itself; that is the expected outcome here.
  stranger.removeAllListeners("console");
  await stranger.goto(url);
  await useToken(stranger, "not-a-token-at-all");
  await stranger.waitForFunction(() => document.querySelector("#connection")?.dataset.state === "error", null, { timeout: T });
  const said = await stranger.$eval("#notice", (e) => e.textContent);
  check(/token/.test(said), `the page says "${said}"`);
  console.log(`ok wrong token refused: ${said}`);

  check(problems.length === 0, problems.join("; "));
  console.log("browser tests passed");
} catch (e) {
  console.error(`FAILED at ${step}: ${e.message}`);
  for (const [i, p] of context.pages().entries()) {
    await p.screenshot({ path: `${out}/failed-${i}.png` }).catch(() => {});
    console.error(`page ${i} ${p.url()}: ${await p.$eval("#connection", (e) => e.textContent).catch(() => "?")}`);
  }
  for (const p of problems) console.error(p);
  status = 1;
} finally {
  await close();
}
process.exit(status);

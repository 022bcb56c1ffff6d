// The console's browser tests (run by tests/tests/console.rs against a real
// laparo-server with tokens): each step asserts one property of issue 12's
// "Must hold", reading the page's state from the DOM (data- attributes, text).
// Usage: node console.mjs URL INSTRUCTOR_TOKEN OUT_DIR [TLS_URL [RECORDINGS_DIR]]
// The server at URL is stopped and started again on request: the script writes
// OUT_DIR/stop and waits for OUT_DIR/stopped, then OUT_DIR/start and waits for
// OUT_DIR/started (tests/tests/console.rs answers).
import { copyFileSync, existsSync, readFileSync, statSync, truncateSync, writeFileSync } from "node:fs";
import { launch, reportFailure, watch } from "./browser.mjs";
import { decodePng } from "./png.mjs";

const [url, token, out, tlsUrl, recordingsDir] = process.argv.slice(2);
const problems = [];
const T = 30_000;
let step = "start";

/** Asks the test for `what` (a file in OUT_DIR) and waits for its answer. */
async function ask(what, answer) {
  writeFileSync(`${out}/${what}`, "");
  for (const t0 = Date.now(); !existsSync(`${out}/${answer}`); ) {
    if (Date.now() - t0 > T) throw new Error(`${step}: no ${answer} after ${what}`);
    await new Promise((r) => setTimeout(r, 100));
  }
}

const liveState = (page, state) =>
  page.waitForFunction((s) => document.querySelector("#connection")?.dataset.state === s, state, { timeout: T });

/** The tip of `instrument` (its gauge's data-tip) once it has stayed put for
 * 800 ms (a slow frame may hold the gauge for a moment). */
async function restingTip(page, instrument) {
  let last = null;
  let same = 0;
  for (const t0 = Date.now(); Date.now() - t0 < T; ) {
    const tip = await page.$eval(`#gauges [data-instrument="${instrument}"]`, (e) => e.dataset.tip);
    same = tip && tip === last ? same + 1 : 0;
    if (same === 2) return tip;
    last = tip;
    await page.waitForTimeout(400);
  }
  throw new Error(`${step}: the ${instrument} tip never came to rest`);
}

/** Waits up to 5 s for the tip of `instrument` to leave `from`; fails saying `what`. */
async function tipMoves(page, instrument, from, what) {
  await page
    .waitForFunction(([i, b]) => document.querySelector(`#gauges [data-instrument="${i}"]`)?.dataset.tip !== b, [instrument, from], { timeout: 5000 })
    .catch(() => {
      throw new Error(`${step}: ${what} left the ${instrument} tip at ${from}`);
    });
}

/** Moves a replay page's seek bar to `t` s and lets go of it, as a user does. */
async function seekTo(page, t) {
  await page.$eval(
    "#seek",
    (e, t) => {
      e.value = String(t);
      e.dispatchEvent(new Event("change"));
    },
    t,
  );
}

/** A replay page as it stands: the states it went through since `__replayStates`
 * was last emptied, the time shown and the connection's state. */
async function replayNow(page) {
  return page.evaluate(() => ({
    states: window.__replayStates,
    time: document.querySelector("#replay").dataset.time,
    connection: document.querySelector("#connection").dataset.state,
  }));
}

function check(cond, what) {
  if (!cond) throw new Error(`${step}: ${what}`);
}

async function useToken(page, t) {
  await page.fill("#token", t);
  await page.click("#token-form button");
}

/** Counts the pixels of a screenshot of the 3D view for which `test(r, g, b)`
 * holds, within the fraction `box` [x0, y0, w, h] of it (all by default). */
async function countPixels(page, test, box = [0, 0, 1, 1]) {
  const { width, height, data } = decodePng(await page.locator("#viewport canvas").screenshot());
  const [x0, y0] = [Math.floor(width * box[0]), Math.floor(height * box[1])];
  const [w, h] = [Math.floor(width * box[2]), Math.floor(height * box[3])];
  let n = 0;
  for (let y = y0; y < y0 + h; y++) {
    for (let x = x0; x < x0 + w; x++) {
      const i = 4 * (y * width + x);
      if (test(data[i], data[i + 1], data[i + 2])) n++;
    }
  }
  return { n, of: w * h };
}

/** Pixels of the held vertices' cyan (green and blue high, red low: no liver,
 * instrument, trocar, arrow or background colour is). */
async function heldPixels(page) {
  return (await countPixels(page, (r, g, b) => g > 170 && b > 170 && r < 130)).n;
}

/** Liver-coloured pixels (red well above green and blue) in the centre of the 3D
 * view, read off a screenshot of it (what the page shows: the WebGL canvas
 * keeps no drawing buffer to read back). */
async function liverPixels(page) {
  const { n, of } = await countPixels(page, (r, g, b) => r > 60 && r > 1.4 * g && r > 1.4 * b, [0.4, 0.4, 0.2, 0.2]);
  return n / of;
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

  // Keys typed into the token field are the field's: they neither roll nor move
  // the instrument; the same key on the page rolls it.
  step = "typing in a field";
  const rollOf = () => driver.$eval("#hud", (e) => /left roll (-?\d+)°/.exec(e.textContent)?.[1]);
  const tipBefore = await driver.$eval('#gauges [data-instrument="left"]', (e) => e.dataset.tip);
  await driver.locator("#token").pressSequentially("qqqe");
  await driver.waitForTimeout(300);
  const typed = { roll: await rollOf(), tip: await driver.$eval('#gauges [data-instrument="left"]', (e) => e.dataset.tip) };
  check(typed.roll === "0" && typed.tip === tipBefore, `typing "qqqe" in the token field rolled left to ${typed.roll}°, tip ${tipBefore} → ${typed.tip}`);
  await driver.fill("#token", token);
  await driver.locator("#token").blur();
  await driver.keyboard.press("q");
  await driver.waitForFunction(() => /left roll -6°/.test(document.querySelector("#hud")?.textContent), null, { timeout: T });
  await driver.keyboard.press("e");
  console.log(`ok typing in the token field left the instrument alone (roll ${typed.roll}°, tip ${typed.tip})`);

  // The held vertices arrive and are drawn: as many points as the state's held
  // count, cyan on the screen.
  step = "held vertices";
  await driver.waitForFunction(
    () => {
      const row = document.querySelector('#gauges [data-instrument="left"]');
      return Number(row?.dataset.heldCount) > 0 && row.dataset.heldDrawn === row.dataset.heldCount;
    },
    null,
    { timeout: T },
  );
  const held = await driver.$eval('#gauges [data-instrument="left"]', (e) => Number(e.dataset.heldDrawn));
  const cyan = await heldPixels(driver);
  check(cyan > 0, `no cyan pixels for the ${held} held vertices`);
  console.log(`ok ${held} held vertices drawn (${cyan} cyan pixels)`);

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

  // The session's recording, replayed while it is still being made, plays to
  // where the file stood and stops there saying so: paused, not ended.
  step = "replay in progress";
  const early = await other.newPage();
  watch(early, "early replay", problems);
  await early.goto(url);
  await useToken(early, token);
  const going = await early.waitForSelector(`#recordings tr[data-recording] >> text=${sessionId}`, { timeout: T });
  const goingFile = await going.evaluate((e) => e.closest("tr").dataset.recording);
  await early.goto(`${url}#/replay/${encodeURIComponent(goingFile)}`);
  await early.waitForFunction(() => Number(document.querySelector("#replay")?.dataset.drawn) > 0, null, { timeout: T });
  await early.selectOption("#speed", "10");
  await early.waitForFunction(() => document.querySelector("#replay")?.dataset.state === "paused", null, { timeout: 60_000 });
  const stood = await early.evaluate(() => ({
    connection: document.querySelector("#connection").textContent,
    error: document.querySelector("#replay").dataset.error ?? "",
  }));
  check(/still being recorded/.test(stood.connection) && !stood.error, `a replay of the recording in progress ended: ${stood.connection} (error: ${stood.error})`);
  console.log(`ok a replay of the recording in progress stops where it stood: ${stood.connection}`);
  await early.close();

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
  // The recording's held vertices are drawn in the replay as live.
  step = "replay: held vertices";
  await driver.waitForFunction(() => Number(document.querySelector('#gauges [data-instrument="left"]')?.dataset.heldDrawn) > 0, null, {
    timeout: T,
  });
  console.log(`ok replay draws ${await driver.$eval('#gauges [data-instrument="left"]', (e) => e.dataset.heldDrawn)} held vertices`);
  // Paused, the replay's time stands still.
  step = "replay: pause";
  await driver.click("#pause");
  await driver.waitForFunction(() => document.querySelector("#replay")?.dataset.state === "paused", null, { timeout: T });
  await driver.waitForTimeout(300);
  const paused = await driver.$eval("#replay", (e) => e.dataset.time);
  await driver.waitForTimeout(1000);
  const still = await driver.$eval("#replay", (e) => e.dataset.time);
  check(paused === still, `paused at ${paused} s, then at ${still} s`);
  console.log(`ok replay paused at ${paused} s stays there`);
  // Sought while paused, it shows the frame at the time asked (within a frame of
  // the recording) and stays paused: the time shown stands still there, and no
  // stream is left open.
  step = "replay: seek while paused";
  // Halfway, or a tenth of the way when paused near halfway: away from the time paused at.
  const seekMax = await driver.$eval("#seek", (e) => Number(e.max));
  const half = Math.round(seekMax * 50) / 100;
  const target = Math.abs(half - Number(paused)) > seekMax / 5 ? half : Math.round(seekMax * 10) / 100;
  await seekTo(driver, target);
  await driver.waitForFunction(() => document.querySelector("#replay")?.dataset.startedAt, null, { timeout: T });
  const landed = await driver.$eval("#replay", (e) => Number(e.dataset.startedAt));
  check(Math.abs(landed - target) <= 1 / 30, `sought ${target} s, landed at ${landed} s`);
  await driver.waitForFunction(() => document.querySelector("#connection")?.dataset.state === "idle", null, { timeout: T });
  await driver.waitForTimeout(300);
  const shownAt = await driver.evaluate(() => ({
    state: document.querySelector("#replay").dataset.state,
    time: document.querySelector("#replay").dataset.time,
    text: document.querySelector("#time").textContent,
  }));
  check(shownAt.state === "paused", `sought while paused, the replay went ${shownAt.state}`);
  check(Math.abs(Number(shownAt.time) - target) <= 1 / 30, `sought ${target} s while paused, the page shows ${shownAt.time} s`);
  check(shownAt.text.startsWith(`${Number(shownAt.time).toFixed(2)} /`), `the time text says "${shownAt.text}" at ${shownAt.time} s`);
  await driver.waitForTimeout(1000);
  const stays = await driver.evaluate(() => ({
    state: document.querySelector("#replay").dataset.state,
    time: document.querySelector("#replay").dataset.time,
    connection: document.querySelector("#connection").dataset.state,
  }));
  check(stays.state === "paused" && stays.time === shownAt.time && stays.connection === "idle", `a second after the seek: ${JSON.stringify(stays)}, shown at ${shownAt.time} s`);
  console.log(`ok replay paused at ${paused} s, sought ${target} s: shows ${shownAt.text}, still paused a second later`);
  // Played from there, it goes on from the time sought.
  step = "replay: play after the seek";
  await driver.click("#play");
  await driver.waitForFunction(() => document.querySelector("#replay")?.dataset.state === "playing", null, { timeout: T });
  await driver.waitForFunction((t) => Number(document.querySelector("#replay")?.dataset.time) > t + 0.1, Number(shownAt.time), { timeout: T });
  const playedFrom = await driver.$eval("#replay", (e) => Number(e.dataset.startedAt));
  check(Math.abs(playedFrom - Number(shownAt.time)) <= 1 / 30, `paused at ${shownAt.time} s, played from ${playedFrom} s`);
  console.log(`ok replay played on from ${playedFrom} s`);
  // Clicked, the seek bar keeps the focus and goes on following the playback.
  step = "replay: seek bar follows after a click";
  await driver.click("#seek");
  const clicked = await driver.$eval("#seek", (e) => Number(e.value));
  await driver.waitForFunction((c) => Number(document.querySelector("#replay")?.dataset.time) > c + 0.3, clicked, { timeout: T });
  await driver.waitForTimeout(200);
  const follows = await driver.evaluate(() => ({
    seek: Number(document.querySelector("#seek").value),
    time: Number(document.querySelector("#replay").dataset.time),
    focused: document.activeElement?.id,
  }));
  check(Math.abs(follows.seek - follows.time) < 0.1, `clicked at ${clicked} s, the bar at ${follows.seek} s while playing at ${follows.time} s`);
  console.log(`ok the seek bar clicked at ${clicked} s follows the playback: ${follows.seek} s at ${follows.time} s (focus on #${follows.focused})`);
  step = "replay: to the end";
  await driver.selectOption("#speed", "10");
  await driver.waitForFunction(() => document.querySelector("#replay")?.dataset.state === "ended", null, { timeout: 60_000 });
  await driver.screenshot({ path: `${out}/replay.png` });
  console.log(`ok replay of ${file} played to its end at ${await driver.$eval("#replay", (e) => e.dataset.time)} s`);
  // Played to its end, a change of speed is kept for the next play and plays
  // nothing; a seek shows the frame at the time sought and stays paused; play
  // then plays from there, at the speed chosen.
  step = "replay: speed after the end";
  const endedAt = await driver.$eval("#replay", (e) => e.dataset.time);
  // Every state the replay goes through from here, as it goes.
  await driver.evaluate(() => {
    const r = document.querySelector("#replay");
    window.__replayStates = [];
    new MutationObserver(() => window.__replayStates.push(r.dataset.state)).observe(r, { attributes: true, attributeFilter: ["data-state"] });
  });
  await driver.selectOption("#speed", "0.25");
  await driver.waitForTimeout(1000);
  const afterSpeed = await replayNow(driver);
  check(
    afterSpeed.states.length === 0 && afterSpeed.time === endedAt && afterSpeed.connection === "ended",
    `the speed changed after the end (at ${endedAt} s): went ${afterSpeed.states.join(", ") || "nowhere"}, at ${afterSpeed.time} s, connection ${afterSpeed.connection}`,
  );
  console.log(`ok a speed changed after the end (at ${endedAt} s) plays nothing`);
  step = "replay: seek after the end";
  await driver.evaluate(() => (window.__replayStates = []));
  const endMax = await driver.$eval("#seek", (e) => Number(e.max));
  const afterEnd = Math.round(endMax * 30) / 100;
  await seekTo(driver, afterEnd);
  await driver.waitForFunction(() => document.querySelector("#replay")?.dataset.startedAt, null, { timeout: T });
  // The frame shown, the stream ends (the check below says if it did not).
  await driver.waitForFunction(() => document.querySelector("#connection")?.dataset.state === "idle", null, { timeout: 5000 }).catch(() => {});
  await driver.waitForTimeout(300);
  const endSought = await driver.$eval("#replay", (e) => e.dataset.time);
  await driver.waitForTimeout(1000);
  const endStays = await replayNow(driver);
  check(
    endStays.states.every((s) => s === "paused") && endStays.time === endSought && endStays.connection === "idle",
    `sought ${afterEnd} s after the end: went ${endStays.states.join(", ")}, at ${endSought} s then ${endStays.time} s a second later, connection ${endStays.connection}`,
  );
  check(Math.abs(Number(endSought) - afterEnd) <= 1 / 30, `sought ${afterEnd} s after the end, the page shows ${endSought} s`);
  console.log(`ok a seek after the end to ${afterEnd} s shows ${endSought} s and stays paused`);
  step = "replay: play after a seek after the end";
  await driver.click("#play");
  await driver.waitForFunction(() => document.querySelector("#replay")?.dataset.state === "playing", null, { timeout: T });
  await driver.waitForFunction((t) => Number(document.querySelector("#replay")?.dataset.time) > t + 0.05, Number(endSought), { timeout: T });
  const resumed = await driver.evaluate(() => ({ from: Number(document.querySelector("#replay").dataset.startedAt), time: Number(document.querySelector("#replay").dataset.time), t: performance.now() }));
  check(Math.abs(resumed.from - Number(endSought)) <= 1 / 30, `sought ${endSought} s after the end, played from ${resumed.from} s`);
  await driver.waitForTimeout(1000);
  const later = await driver.evaluate(() => ({ time: Number(document.querySelector("#replay").dataset.time), t: performance.now() }));
  // At 0.25×, about a quarter of the wall time passed; at the 10× played before, ten times it.
  const rate = (later.time - resumed.time) / ((later.t - resumed.t) / 1000);
  check(rate < 1, `played after the end at ${rate.toFixed(2)}× with 0.25× chosen after the end`);
  console.log(`ok played from ${resumed.from} s at the speed chosen after the end (${rate.toFixed(2)}× for 0.25×)`);

  // A recording cut short (a copy without its end, as a stopped server leaves
  // one) is listed unfinished, with how to recover it instead of a replay link.
  if (recordingsDir) {
    step = "unfinished recording";
    const cut = `cut-${file}`;
    copyFileSync(`${recordingsDir}/${file}`, `${recordingsDir}/${cut}`);
    truncateSync(`${recordingsDir}/${cut}`, Math.floor(statSync(`${recordingsDir}/${file}`).size * 0.6));
    await driver.goto(`${url}#/`);
    const cutRow = await driver.waitForSelector(`#recordings tr[data-recording="${cut}"]`, { timeout: T });
    const said = await cutRow.evaluate((e) => ({ text: e.lastElementChild.textContent, links: e.querySelectorAll("a").length }));
    check(said.links === 0 && /unfinished: recover with `laparo recordings recover`/.test(said.text), `${cut} offers ${said.links} links, "${said.text}"`);
    check(await driver.$(`#recordings tr[data-recording="${file}"] a.replay`), `${file} lost its replay link`);
    console.log(`ok an unfinished recording says "${said.text}"`);
  }

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

  // A gamepad drives an instrument: the left stick pivots it, the left trigger
  // inserts it; its vibration grows with the force.
  step = "gamepad";
  await driver.goto(`${url}#/`);
  await driver.waitForSelector('#scenes tr[data-scene="default"]', { timeout: T });
  await driver.click("#create");
  await driver.waitForSelector('#live[data-mode="drive"]', { timeout: T });
  const padSession = await driver.$eval("#live", (e) => e.dataset.session);
  const pad = await context.newPage();
  watch(pad, "gamepad", problems);
  await pad.addInitScript(() => {
    const button = (i) => ({ get pressed() { return window.__pad.buttons[i] > 0; }, get value() { return window.__pad.buttons[i]; }, touched: false });
    window.__pad = { axes: [0, 0, 0, 0], buttons: new Array(16).fill(0), rumble: [] };
    const gamepad = {
      id: "fake pad",
      index: 0,
      connected: true,
      mapping: "standard",
      timestamp: 0,
      get axes() { return window.__pad.axes; },
      buttons: Array.from({ length: 16 }, (_, i) => button(i)),
      vibrationActuator: {
        type: "dual-rumble",
        playEffect: (type, p) => {
          window.__pad.rumble.push(p.strongMagnitude);
          return Promise.resolve("complete");
        },
      },
    };
    navigator.getGamepads = () => [gamepad, null, null, null];
  });
  await pad.goto(`${url}#/`);
  await useToken(pad, token);
  await pad.goto(`${url}#/live/${encodeURIComponent(padSession)}?drive=right`);
  await liveState(pad, "live");
  const tipOf = () => pad.$eval('#gauges [data-instrument="right"]', (e) => e.dataset.tip);
  await pad.waitForFunction(() => document.querySelector('#gauges [data-instrument="right"]')?.dataset.tip, null, { timeout: T });
  const before = await tipOf();
  await pad.evaluate(() => (window.__pad.axes[0] = 0.4));
  await pad.waitForFunction((b) => document.querySelector('#gauges [data-instrument="right"]')?.dataset.tip !== b, before, { timeout: T });
  await pad.evaluate(() => (window.__pad.axes[0] = 0));
  console.log(`ok gamepad stick moved the tip from ${before} to ${await tipOf()}`);
  await pad.evaluate(() => (window.__pad.buttons[6] = 1));
  await pad.waitForFunction(() => Number(document.querySelector('#gauges [data-instrument="right"]')?.dataset.forceN) > 0.3, null, {
    timeout: T,
  });
  await pad.evaluate(() => (window.__pad.buttons[6] = 0));
  const rumble = await pad.evaluate(() => window.__pad.rumble);
  check(rumble.length > 1 && rumble[0] > 0, `vibration ${JSON.stringify(rumble.slice(0, 5))}`);
  check(rumble[rumble.length - 1] > rumble[0], `vibration from ${rumble[0]} to ${rumble[rumble.length - 1]} as the force grew`);
  console.log(`ok gamepad vibration grew with the force: ${rumble[0].toFixed(3)} → ${rumble[rumble.length - 1].toFixed(3)}`);
  // How the page sends the poses: sampled at 250 Hz (4 ms apart), in batches.
  const sent = await pad.$eval("#live", (e) => ({ calls: Number(e.dataset.poseCalls), poses: Number(e.dataset.posesSent), spacing: Number(e.dataset.poseSpacingMs) }));
  check(Math.abs(sent.spacing - 4) < 0.01, `poses ${sent.spacing} ms apart`);
  check(sent.poses > sent.calls, `${sent.poses} poses in ${sent.calls} calls`);
  console.log(`ok ${sent.poses} poses 4 ms apart in ${sent.calls} calls`);
  // The left shoulder held with the left trigger pulls the instrument back, out
  // of the tissue, without rolling it.
  step = "gamepad: pulling back";
  await pad.evaluate(() => (window.__pad.buttons[4] = window.__pad.buttons[6] = 1));
  await pad.waitForFunction(() => Number(document.querySelector('#gauges [data-instrument="right"]')?.dataset.forceN) === 0, null, { timeout: T });
  await pad.evaluate(() => (window.__pad.buttons[4] = window.__pad.buttons[6] = 0));
  const pulledRoll = await pad.$eval("#hud", (e) => /right roll (-?\d+)°/.exec(e.textContent)?.[1]);
  check(pulledRoll === "0", `pulling back rolled the instrument to ${pulledRoll}°`);
  console.log("ok LB with LT pulled the instrument out of the tissue without rolling it");

  // An instrument another station holds is waited for, and taken once it is let
  // go: the pad's page asks for the left instrument, which the driver holds.
  step = "claimed instrument";
  await pad.goto(`${url}#/live/${encodeURIComponent(padSession)}?drive=left`);
  await liveState(pad, "reconnecting");
  const waiting = await pad.$eval("#notice", (e) => e.textContent);
  check(/already claimed/.test(waiting) && /waiting for its release/.test(waiting), `the page says "${waiting}"`);
  await driver.goto(`${url}#/`);
  await liveState(pad, "live");
  await pad.waitForFunction(() => document.querySelector('#gauges [data-instrument="left"]')?.dataset.tip, null, { timeout: T });
  console.log(`ok a claimed instrument was waited for ("${waiting}") and taken once let go`);

  // A session created with the record box untouched is recorded as its scene
  // declares: the default scene records.
  step = "recorded as the scene declares";
  const recording = await driver.waitForSelector(`#sessions tr[data-session="${padSession}"] td:nth-child(9)`, { timeout: T });
  const said9 = await recording.textContent();
  check(/^recording /.test(said9), `the session created without touching the record box says "${said9}"`);
  console.log(`ok a session of a scene that records is recorded: "${said9}"`);

  // The sessions page, refreshed every 2 s, keeps an action's error (here a
  // session of a scene there is none of) and the keyboard's focus.
  step = "sessions page: notice and focus kept";
  await driver.$eval("#new-scene", (e) => {
    e.append(new Option("no-such-scene", "no-such-scene"));
    e.value = "no-such-scene";
  });
  await driver.click("#create");
  await driver.waitForFunction(() => /creating a session/.test(document.querySelector("#notice")?.textContent), null, { timeout: T });
  const link = `#sessions tr[data-session="${padSession}"] a.observe`;
  await driver.focus(link);
  await driver.waitForTimeout(2500);
  const kept = await driver.$eval("#notice", (e) => (e.hidden ? "" : e.textContent));
  check(/creating a session/.test(kept), `after a refresh the notice says "${kept}"`);
  const focused = await driver.$eval(link, (e) => e === document.activeElement);
  check(focused, `after a refresh the focus is on ${await driver.evaluate(() => document.activeElement?.outerHTML.slice(0, 80))}`);
  console.log(`ok a refresh kept the notice "${kept}" and the focus on the observe link`);

  // A station's client name of 250 characters without a space wraps in the
  // sessions table instead of widening it past the window.
  step = "long client name";
  await ask("station", "station-joined");
  const longSession = readFileSync(`${out}/station-joined`, "utf8");
  await driver.waitForFunction((s) => /n{250}/.test(document.querySelector(`#sessions tr[data-session="${s}"]`)?.textContent), longSession, { timeout: T });
  const widths = await driver.evaluate(() => ({ table: document.querySelector("#sessions").scrollWidth, page: document.documentElement.scrollWidth, window: window.innerWidth }));
  check(widths.table <= widths.window && widths.page <= widths.window, `with a 250-character client name the sessions table is ${widths.table} px wide, the page ${widths.page} px, in a ${widths.window} px window`);
  await driver.click(`#sessions tr[data-session="${longSession}"] button.close`);
  await driver.waitForSelector(`#sessions tr[data-session="${longSession}"]`, { state: "detached", timeout: T });
  console.log(`ok a 250-character client name keeps the sessions table ${widths.table} px wide in a ${widths.window} px window`);

  // A browser station joins under the name given in its page (the sessions
  // table shows it), kept across a reload; a name over the server's 256 bytes is
  // cut at a character's boundary; emptied, it is "browser console" again.
  step = "station name";
  const namer = await context.newPage();
  watch(namer, "namer", problems);
  await namer.goto(`${url}#/`);
  await useToken(namer, token);
  await namer.goto(`${url}#/live/${encodeURIComponent(padSession)}?drive=right`);
  await liveState(namer, "live");
  const listed = (name) =>
    driver
      .waitForFunction(([s, n]) => document.querySelector(`#sessions tr[data-session="${s}"]`)?.textContent.includes(` ${n} (right)`), [padSession, name], { timeout: T })
      .catch(async () => {
        throw new Error(`${step}: the sessions table never listed "${name}" for the right instrument: ${await driver.$eval(`#sessions tr[data-session="${padSession}"]`, (e) => e.textContent).catch(() => "no row")}`);
      });
  const rename = async (name) => {
    await namer.fill("#client-name", name);
    await namer.press("#client-name", "Enter");
  };
  await listed("browser console");
  await rename("trainee Zoë");
  await listed("trainee Zoë");
  await liveState(namer, "live");
  await namer.reload();
  await liveState(namer, "live");
  const reloaded = await namer.$eval("#client-name", (e) => e.value);
  check(reloaded === "trainee Zoë", `after a reload the name field says "${reloaded}"`);
  await listed("trainee Zoë");
  console.log(`ok a station named "trainee Zoë" in its page is listed so, after a reload too`);
  step = "station name: cut to fit";
  await rename("é".repeat(150));
  const cut = await namer.$eval("#client-name", (e) => e.value);
  check(cut === "é".repeat(128), `a name of 150 "é" (300 bytes) became ${cut.length} characters, ${new TextEncoder().encode(cut).length} bytes`);
  await listed(cut);
  await rename("");
  await listed("browser console");
  console.log(`ok a 300-byte name was cut to ${new TextEncoder().encode(cut).length} bytes (${cut.length} "é") and listed; emptied, "browser console" again`);
  // The name is the tab's: two trainees in two tabs of one browser keep their
  // own. A new tab starts with the last name given in this browser; a name
  // given there leaves the first tab's alone, across its reload too.
  step = "station name: per tab";
  await rename("trainee Ann");
  await listed("trainee Ann");
  const second = await context.newPage();
  watch(second, "second tab", problems);
  await second.goto(`${url}#/`);
  await useToken(second, token);
  // The right instrument is the first tab's: this one waits for it, its name field shown.
  await second.goto(`${url}#/live/${encodeURIComponent(padSession)}?drive=right`);
  await second.waitForSelector("#client-name", { timeout: T });
  const seeded = await second.$eval("#client-name", (e) => e.value);
  check(seeded === "trainee Ann", `a new tab's name field says "${seeded}", the last name given being "trainee Ann"`);
  await second.fill("#client-name", "trainee Bob");
  await second.press("#client-name", "Enter");
  await second.close();
  await namer.reload();
  await liveState(namer, "live");
  const own = await namer.$eval("#client-name", (e) => e.value);
  check(own === "trainee Ann", `a tab named "trainee Ann" says "${own}" after a reload, another tab having been named "trainee Bob"`);
  await listed("trainee Ann");
  console.log(`ok a new tab started as "${seeded}", was named "trainee Bob", and the first tab kept "${own}"`);

  // A pose batch on its way while the name changes fails only because the
  // rejoin ended its station: that is not said as poses not sent. The batch is
  // held until the station under the new name has joined (the old one gone),
  // then let go, and the server refuses it for a handle it no longer knows.
  step = "station name: a batch in flight while renaming";
  await namer.evaluate(() => {
    const n = document.querySelector("#notice");
    window.__notices = [];
    new MutationObserver(() => window.__notices.push(n.textContent)).observe(n, { childList: true, characterData: true, subtree: true });
  });
  let inFlight = null;
  let sentAfter = 0;
  await namer.route("**/laparo.v1.Station/SendPoses", (r) => {
    if (!inFlight) inFlight = r;
    else {
      sentAfter++;
      return r.continue();
    }
  });
  for (const t0 = Date.now(); !inFlight; await namer.waitForTimeout(50)) check(Date.now() - t0 < T, "no SendPoses call to hold");
  await rename("trainee Cy");
  await listed("trainee Cy");
  await liveState(namer, "live");
  await namer.waitForTimeout(500);
  await inFlight.continue();
  const answer = await inFlight.request().response();
  check(answer, "the batch held over the rejoin got no answer");
  const grpcStatus = (await answer.allHeaders())["grpc-status"] ?? /grpc-status: ?(\d+)/.exec((await answer.body()).toString("latin1"))?.[1];
  check(grpcStatus === "5", `the batch held over the rejoin was answered grpc-status ${grpcStatus}, not NOT_FOUND (5)`);
  // The held call settled, the page sends again; whatever it said is in __notices.
  for (const t0 = Date.now(); sentAfter === 0; await namer.waitForTimeout(50)) check(Date.now() - t0 < T, "no SendPoses call after the held one");
  await namer.waitForTimeout(300);
  await namer.unroute("**/laparo.v1.Station/SendPoses");
  const notSent = (await namer.evaluate(() => window.__notices)).filter((t) => /poses not sent/.test(t));
  check(notSent.length === 0, `a batch in flight over the rejoin under a new name was said: "${notSent[0]}"`);
  await liveState(namer, "live");
  await listed("trainee Cy");
  console.log(`ok a batch in flight over a rejoin, refused NOT_FOUND for the old station, was not said as poses not sent`);
  await namer.close();

  // A malformed address is said, over the sessions list.
  step = "malformed address";
  await driver.goto(`${url}#/live/%`);
  await driver.waitForFunction(() => /not a valid console address/.test(document.querySelector("#notice")?.textContent), null, { timeout: T });
  await driver.waitForSelector('#scenes tr[data-scene="default"]', { timeout: T });
  console.log(`ok a malformed address is said: ${await driver.$eval("#notice", (e) => e.textContent)}`);

  // A hidden tab draws no frames, so it samples no poses: with the frame loop
  // stopped, the station stays live past the server's station timeout (5 s) on
  // its heartbeat.
  step = "hidden tab";
  await pad.evaluate(() => {
    window.__states = [];
    const c = document.querySelector("#connection");
    new MutationObserver(() => window.__states.push(c.dataset.state)).observe(c, { attributes: true });
    window.requestAnimationFrame = () => 0;
  });
  await pad.waitForTimeout(6500);
  const states = await pad.evaluate(() => window.__states.filter((s) => s !== "live"));
  check(states.length === 0, `without frames the station went ${states.join(", ")}`);
  console.log("ok a page drawing no frames kept its instrument past the station timeout");

  // A reconnect builds the scene again and frees what the last one built: the
  // GPU holds as many geometries after it as before. Poses and heartbeats
  // answered UNAVAILABLE on the way never reach the server, which times the
  // station out.
  step = "reconnect";
  await pad.reload();
  await liveState(pad, "live");
  const drawnNow = () => pad.$eval("#live", (e) => Number(e.dataset.drawn));
  const drawnPast = (n) => pad.waitForFunction((n) => Number(document.querySelector("#live")?.dataset.drawn) > n, n, { timeout: T });
  await drawnPast(await drawnNow());
  const geometries = await pad.$eval("#live", (e) => Number(e.dataset.geometries));
  // Moved off its start pose first: the reconnect must keep where it was left.
  const leftTip = () => pad.$eval('#gauges [data-instrument="left"]', (e) => e.dataset.tip);
  await pad.waitForFunction(() => document.querySelector('#gauges [data-instrument="left"]')?.dataset.tip, null, { timeout: T });
  const startTip = await leftTip();
  await pad.evaluate(() => (window.__pad.axes[0] = 0.4));
  await pad.waitForFunction((b) => document.querySelector('#gauges [data-instrument="left"]')?.dataset.tip !== b, startTip, { timeout: T });
  await pad.evaluate(() => (window.__pad.axes[0] = 0));
  await pad.waitForTimeout(300);
  const leftAt = await leftTip();
  const sends = "**/laparo.v1.Station/SendPoses";
  const dropped = { status: 200, headers: { "content-type": "application/grpc-web+proto", "grpc-status": "14", "grpc-message": "dropped" } };
  let refused = 0;
  await pad.route(sends, (r) => {
    refused++;
    return r.fulfill(dropped);
  });
  await liveState(pad, "reconnecting");
  // The server ended the station (DEADLINE_EXCEEDED, its station timeout): the
  // page says the server's reason, not that a call of its own went unanswered.
  const timedOut = await pad.$eval("#notice", (e) => e.textContent);
  check(/connection lost: station \d+ sent nothing/.test(timedOut) && !/no answer within/.test(timedOut), `notice on the station timeout: ${timedOut}`);
  await pad.unroute(sends);
  // Failed calls are made again after a backoff, not at every frame.
  check(refused < 30, `${refused} SendPoses calls while they failed`);
  await liveState(pad, "live");
  await drawnPast(await drawnNow());
  const again = await pad.$eval("#live", (e) => Number(e.dataset.geometries));
  check(geometries > 0 && again === geometries, `${geometries} geometries on the GPU before the reconnect, ${again} after`);
  console.log(`ok a reconnect built the scene again and freed the last one: ${again} geometries on the GPU`);
  step = "reconnect: the pose is kept";
  await pad
    .waitForFunction((at) => document.querySelector('#gauges [data-instrument="left"]')?.dataset.tip === at, leftAt, { timeout: 5000 })
    .catch(async () => {
      throw new Error(`${step}: the tip was at ${leftAt} before the reconnect (${startTip} at the start), at ${await leftTip()} after`);
    });
  console.log(`ok a reconnect kept the instrument where it was left: tip at ${leftAt} (${refused} calls refused meanwhile)`);

  // Poses refused for a moment are said, and no longer once sent again.
  step = "poses refused, then sent";
  let failures = 2;
  await pad.route(sends, (r) => (failures-- > 0 ? r.fulfill(dropped) : r.continue()));
  await pad.waitForFunction(() => /poses not sent/.test(document.querySelector("#notice")?.textContent), null, { timeout: T });
  await pad.waitForFunction(() => document.querySelector("#notice")?.hidden, null, { timeout: 10_000 });
  await pad.unroute(sends);
  console.log("ok poses refused for a moment were said, and no longer once sent again");

  // An evicted station is told by whom and stays out: its page does not join
  // again by itself.
  step = "evict";
  await driver.goto(`${url}#/`);
  await driver.click(`#sessions tr[data-session="${padSession}"] button.evict`);
  await liveState(pad, "ended");
  const evicted = await pad.$eval("#connection", (e) => e.textContent);
  check(/evicted by `instructor`/.test(evicted), `the evicted page says "${evicted}"`);
  await pad.waitForTimeout(2000);
  const after = await pad.$eval("#connection", (e) => e.dataset.state);
  check(after === "ended", `the evicted page went ${after}`);
  console.log(`ok an evicted page stays out: ${evicted}`);
  await pad.close();

  // Both instruments of a session driven from one page (the pad's station is
  // gone): the layout in a narrow window, a drag whose release was missed,
  // shift+wheel as a horizontal scroll, the keyboard, and the token entered again.
  // Asked for a third, the page claims the two it can move and says so: a third
  // claimed would be held from every other station and never moved (a scene
  // without `extra` would refuse the whole claim).
  step = "two instruments";
  await driver.goto(`${url}#/live/${encodeURIComponent(padSession)}?drive=left,right,extra`);
  await liveState(driver, "live");
  await driver.waitForFunction(() => [...document.querySelectorAll("#gauges [data-instrument]")].every((e) => e.dataset.held && e.dataset.tip), null, { timeout: T });
  const notDriven = await driver.$eval("#not-driven", (e) => e.textContent);
  check(/not claimed: extra/.test(notDriven), `a third instrument asked for: ${notDriven}`);
  console.log(`ok a page asked for three instruments drives two: ${notDriven}`);
  step = "narrow window";
  await driver.setViewportSize({ width: 360, height: 640 });
  const narrow = await driver.$eval("#viewport canvas", (e) => e.getBoundingClientRect().width);
  await driver.setViewportSize({ width: 1000, height: 700 });
  check(narrow >= 300, `in a 360 px window the 3D view is ${narrow} px wide`);
  console.log(`ok in a 360 px window the 3D view is ${narrow} px wide`);
  // A press, a move, then moves with the button up and no release seen (as
  // when it is released outside the window): hovering does not pivot.
  step = "missed release";
  const c2 = await driver.$eval("#viewport canvas", (e) => {
    const r = e.getBoundingClientRect();
    return { x: r.x + r.width / 2, y: r.y + r.height / 2 };
  });
  const cdp = await context.newCDPSession(driver);
  const mouse = (type, dx, buttons) =>
    cdp.send("Input.dispatchMouseEvent", { type, x: c2.x + dx, y: c2.y, button: type === "mouseMoved" ? (buttons ? "left" : "none") : "left", buttons, clickCount: 1 });
  await mouse("mousePressed", 0, 1);
  await mouse("mouseMoved", 4, 1);
  await mouse("mouseMoved", 6, 0);
  const unpressed = await restingTip(driver, "left");
  for (const dx of [20, 40, 60, 80]) await mouse("mouseMoved", dx, 0);
  await driver.waitForTimeout(300);
  const hovered = await restingTip(driver, "left");
  await mouse("mouseReleased", 80, 0);
  await cdp.detach();
  check(hovered === unpressed, `hovering with the button up moved the left tip from ${unpressed} to ${hovered}`);
  console.log(`ok hovering after a missed release left the tip at ${hovered}`);
  // Shift+wheel sent as a horizontal scroll inserts the second instrument.
  step = "shift+wheel sideways";
  const [left1, right1] = [await restingTip(driver, "left"), await restingTip(driver, "right")];
  await driver.$eval("#viewport canvas", (c) => {
    for (let i = 0; i < 4; i++) c.dispatchEvent(new WheelEvent("wheel", { deltaX: 100, deltaY: 0, shiftKey: true, bubbles: true, cancelable: true }));
  });
  await tipMoves(driver, "right", right1, "shift+wheel with only deltaX");
  check((await restingTip(driver, "left")) === left1, "shift+wheel moved the left instrument");
  console.log(`ok shift+wheel as deltaX inserted the right instrument: ${right1} → ${await restingTip(driver, "right")}`);
  // The arrows pivot the first instrument, W inserts it.
  step = "keyboard";
  const left2 = await restingTip(driver, "left");
  for (let i = 0; i < 3; i++) await driver.keyboard.press("ArrowLeft");
  await tipMoves(driver, "left", left2, "ArrowLeft");
  const left3 = await restingTip(driver, "left");
  for (let i = 0; i < 3; i++) await driver.keyboard.press("w");
  await tipMoves(driver, "left", left3, "W");
  console.log(`ok the keyboard pivoted the left tip (${left2} → ${left3}) and inserted it (→ ${await restingTip(driver, "left")})`);
  // The token entered again (the header's "use") joins again, the instruments
  // where they were: moved off the start pose first (by the keys above too).
  step = "token entered again";
  const left4 = await restingTip(driver, "left");
  for (let i = 0; i < 5; i++) await driver.keyboard.press("ArrowUp");
  await tipMoves(driver, "left", left4, "ArrowUp");
  const leftKept = await restingTip(driver, "left");
  const heldBy = await driver.$eval('#gauges [data-instrument="left"]', (e) => e.dataset.held);
  await useToken(driver, token);
  await liveState(driver, "live");
  await driver.waitForFunction((h) => !["", h].includes(document.querySelector('#gauges [data-instrument="left"]')?.dataset.held ?? ""), heldBy, { timeout: T });
  await driver.waitForTimeout(500);
  const leftAgain = await restingTip(driver, "left");
  const apartMm = 1000 * Math.hypot(...leftKept.split(",").map((v, i) => Number(v) - Number(leftAgain.split(",")[i])));
  check(apartMm < 0.5, `the left tip was at ${leftKept} before the token was entered again, at ${leftAgain} after`);
  console.log(`ok the token entered again kept the left tip at ${leftKept} (${leftAgain} after, ${apartMm.toFixed(2)} mm apart)`);

  // A live view left frees its WebGL context at once: a browser keeps about 16,
  // and a context only disposed stays until garbage collection, so switching
  // views a few dozen times made chromium drop the oldest.
  step = "switching views";
  for (let i = 0; i < 3; i++) {
    await driver.goto(`${url}#/live/${encodeURIComponent(padSession)}`);
    await driver.waitForFunction(() => Number(document.querySelector("#live")?.dataset.drawn) > 0, null, { timeout: T });
    await driver.evaluate(() => (window.__leftCanvas = document.querySelector("#viewport canvas")));
    await driver.goto(`${url}#/`);
    await driver.waitForSelector('#scenes tr[data-scene="default"]', { timeout: T });
    const lost = await driver.evaluate(() => window.__leftCanvas.getContext("webgl2")?.isContextLost());
    check(lost === true, `the WebGL context of live view ${i + 1} is ${lost === false ? "still held" : lost} after leaving it`);
  }
  console.log("ok each live view left released its WebGL context");

  // A restarted server: the page says the connection is lost and comes back.
  step = "restart";
  for (const p of context.pages()) await p.close();
  const lobby = await context.newPage();
  // The browser logs the refused calls itself while the server is away.
  lobby.on("pageerror", (e) => problems.push(`lobby: uncaught ${e.message}`));
  await lobby.goto(url);
  await useToken(lobby, token);
  await lobby.waitForSelector('#scenes tr[data-scene="default"]', { timeout: T });
  // A replay playing while the server is away plays on once it is back.
  const rewatch = await context.newPage();
  rewatch.on("pageerror", (e) => problems.push(`rewatch: uncaught ${e.message}`));
  await rewatch.goto(url);
  await useToken(rewatch, token);
  await rewatch.goto(`${url}#/replay/${encodeURIComponent(file)}`);
  await liveState(rewatch, "live");
  await rewatch.selectOption("#speed", "0.25");
  await liveState(rewatch, "live");
  await ask("stop", "stopped");
  await liveState(lobby, "reconnecting");
  const lost = await lobby.$eval("#notice", (e) => e.textContent);
  check(/connection lost/.test(lost), `the page says "${lost}"`);
  await rewatch.waitForFunction(() => document.querySelector("#replay")?.dataset.error, null, { timeout: T });
  await ask("start", "started");
  await liveState(lobby, "live");
  await lobby.waitForSelector('#scenes tr[data-scene="default"]', { timeout: T });
  console.log(`ok server restarted: the page said "${lost}" and came back`);
  step = "restart: the replay plays on";
  await liveState(rewatch, "live");
  const replayed = await rewatch.$eval("#replay", (e) => ({ error: e.dataset.error, notice: document.querySelector("#notice").hidden }));
  check(replayed.error === undefined && replayed.notice, `the replay plays again, still saying "${replayed.error}"`);
  console.log(`ok the replay played on after the restart from ${await rewatch.$eval("#replay", (e) => e.dataset.time)} s`);

  // Over TLS: the page loads over https and lists the scenes.
  if (tlsUrl) {
    step = "tls";
    const secure = await launch(["--ignore-certificate-errors"]);
    try {
      const page = await secure.context.newPage();
      watch(page, "tls", problems);
      await page.goto(tlsUrl);
      await useToken(page, token);
      await page.waitForSelector('#scenes tr[data-scene="default"]', { timeout: T });
      check(page.url().startsWith("https:"), page.url());
      console.log(`ok console over TLS at ${tlsUrl} lists the scenes`);
      // A station over TLS: the browser speaks HTTP/2 there (ALPN), so the
      // instrument's streams (Station.Attach out, SendPoses in) run over it.
      step = "tls: driving";
      await page.click("#create");
      await page.waitForSelector('#live[data-mode="drive"]', { timeout: T });
      await liveState(page, "live");
      const c = await page.$eval("#viewport canvas", (e) => {
        const r = e.getBoundingClientRect();
        return { x: r.x + r.width / 2, y: r.y + r.height / 2 };
      });
      await page.mouse.move(c.x, c.y);
      let tlsForce = 0;
      for (let i = 0; i < 100 && tlsForce <= 0; i++) {
        await page.mouse.wheel(0, 100);
        await page.waitForTimeout(60);
        tlsForce = await page.$eval('#gauges [data-instrument="left"]', (e) => Number(e.dataset.forceN));
      }
      check(tlsForce > 0, `the left force gauge reads ${tlsForce} N after inserting over TLS`);
      const protocols = await page.evaluate(() => [
        ...new Set(performance.getEntriesByType("resource").map((e) => e.nextHopProtocol)),
      ]);
      check(protocols.includes("h2"), `the page's requests went over ${protocols.join(", ")}, not HTTP/2`);
      console.log(`ok an instrument driven over TLS (${protocols.join(", ")}): force ${tlsForce.toFixed(3)} N`);
      // This server admits 100 poses a second per instrument (console.rs), and
      // says so when the station joins: the page samples at that, not at 250 Hz,
      // and no pose is refused.
      step = "tls: pose limit";
      await page.waitForTimeout(4000);
      const limited = await page.$eval("#live", (e) => ({ rate: e.dataset.poseRateHz, spacing: Number(e.dataset.poseSpacingMs) }));
      check(limited.rate === "100", `the page samples at ${limited.rate} Hz on a server that admits 100`);
      check(Math.abs(limited.spacing - 10) < 0.01, `poses ${limited.spacing} ms apart on a server that admits 100 a second`);
      const tlsNotice = await page.$eval("#notice", (e) => e.textContent);
      check(!/rejected|limit/.test(tlsNotice), `notice: ${tlsNotice}`);
      console.log(`ok poses sampled at the server's limit, ${limited.rate} Hz (${limited.spacing} ms apart), none refused`);
    } finally {
      await secure.close();
    }
  }

  check(problems.length === 0, problems.join("; "));
  console.log("browser tests passed");
} catch (e) {
  await reportFailure(context, out, "failed", step, e, problems);
  status = 1;
} finally {
  await close();
}
process.exit(status);

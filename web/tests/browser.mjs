// Launching Debian's chromium for the console's browser tests and measurements:
// headless, no sandbox (containers), no GPU (SwiftShader draws WebGL), and none
// of the background networking that hangs on a closed network.
import { mkdtempSync, rmSync } from "node:fs";
import { tmpdir } from "node:os";
import { join } from "node:path";
import { chromium } from "playwright-core";

export const CHROMIUM = process.env.LAPARO_CHROMIUM || "/usr/bin/chromium";

/** A browser of its own (a fresh profile); `args`: more command-line switches. */
export async function launch(args = []) {
  const profile = mkdtempSync(join(tmpdir(), "laparo-chromium-"));
  const context = await chromium.launchPersistentContext(profile, {
    executablePath: CHROMIUM,
    headless: true,
    viewport: { width: 1000, height: 700 },
    args: [
      "--headless",
      "--no-sandbox",
      "--disable-gpu",
      "--disable-quic",
      "--no-first-run",
      "--disable-background-networking",
      "--disable-component-update",
      "--disable-sync",
      "--enable-unsafe-swiftshader",
      "--use-angle=swiftshader",
      ...args,
    ],
  });
  const close = async () => {
    await context.close();
    rmSync(profile, { recursive: true, force: true });
  };
  return { context, close };
}

/** Fails the run on any uncaught exception or console error of a page. */
export function watch(page, name, problems) {
  page.on("pageerror", (e) => problems.push(`${name}: uncaught ${e.message}`));
  page.on("console", (m) => {
    if (m.type() === "error") problems.push(`${name}: console error ${m.text()}`);
  });
}

// Creates a session of `scene` from the sessions page `lobby` (at `url`) as an
// instructor, goes back to the list, and returns the session's id.
export async function createSession(lobby, url, scene) {
  await lobby.waitForSelector(`#new-scene option[value="${scene}"]`, { state: "attached", timeout: 30_000 });
  await lobby.selectOption("#new-scene", scene);
  await lobby.click("#create");
  await lobby.waitForSelector("#live[data-session]");
  const session = await lobby.$eval("#live", (e) => e.dataset.session);
  await lobby.goto(`${url}#/`);
  return session;
}

/** Says where a run failed (`step`, the error `e`, the pages' URLs and connection
 * states, the `problems` watched) and saves a screenshot of each page of
 * `context` as OUT/`prefix`-K.png. */
export async function reportFailure(context, out, prefix, step, e, problems) {
  console.error(`FAILED at ${step}: ${e.message}`);
  for (const [i, p] of context.pages().entries()) {
    await p.screenshot({ path: `${out}/${prefix}-${i}.png` }).catch(() => {});
    console.error(`page ${i} ${p.url()}: ${await p.$eval("#connection", (e) => e.textContent).catch(() => "?")}`);
  }
  for (const p of problems) console.error(p);
}

// The laparo console: one page, routed by the URL's hash.
//   #/                      sessions, scenes, recordings
//   #/live/ID               observe session ID
//   #/live/ID?drive=a,b     drive instruments a and b of session ID
//   #/replay/FILE           replay a recording
import "./style.css";
import { live } from "./live";
import type { Handover } from "./live";
import { replay } from "./replay";
import { sessionsPage } from "./sessions";
import { notice, setConnection } from "./status";
import { setToken, token } from "./token";

let current: AbortController | null = null;
/** The live view shown, if one is. */
let shown: Handover | null = null;

/** Shows the view the address names, in place of the one shown. `resume`: a
 * live view of the same session takes over the instruments of the one it
 * replaces where they were (the token changed, the view did not). */
function route(resume = false): void {
  const previous = resume ? shown : null;
  shown = null;
  current?.abort();
  current = new AbortController();
  const signal = current.signal;
  notice(null);
  delete document.body.dataset.error;
  setConnection("idle");
  const app = document.getElementById("app")!;
  const [path, query = ""] = location.hash.replace(/^#/, "").split("?");
  const params = new URLSearchParams(query);
  let parts: string[];
  try {
    parts = path.split("/").filter(Boolean).map(decodeURIComponent);
  } catch {
    // A malformed escape (`#/live/%`): said, over the sessions list, rather than
    // thrown with the left view still on the screen.
    sessionsPage(app, signal);
    notice(`the address ${location.hash} is not a valid console address`);
    return;
  }
  if (parts[0] === "live" && parts[1]) {
    const drive = params.get("drive");
    shown = live(app, { sessionId: parts[1], instruments: drive ? drive.split(",").filter(Boolean) : [], resume: previous ?? undefined }, signal);
  } else if (parts[0] === "replay" && parts[1]) {
    replay(app, parts[1], signal);
  } else {
    sessionsPage(app, signal);
  }
}

const input = document.getElementById("token") as HTMLInputElement;
input.value = token();
document.getElementById("token-form")!.addEventListener("submit", (e) => {
  e.preventDefault();
  setToken(input.value.trim());
  route(true);
});
window.addEventListener("hashchange", () => route());
// Nothing may fail silently: an error nobody caught is said on the page (and
// still reported to the browser, where the tests see it).
window.addEventListener("unhandledrejection", (e) => notice(`unexpected error: ${e.reason}`));
window.addEventListener("error", (e) => notice(`unexpected error: ${e.message}`));
route();

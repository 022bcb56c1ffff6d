// The name a browser station joins with (Station.Attach's client_name), which the
// sessions table shows beside its station id: what the trainee gave in the live
// page, kept per tab (sessionStorage) across reloads and sessions, so that two
// trainees in two tabs of one browser are told apart; a tab without one yet
// starts with the last name given in this browser (localStorage); "browser
// console" when none is given.

const KEY = "laparo.clientName";

export const DEFAULT_NAME = "browser console";

/** The server refuses a client name longer than this, in bytes of UTF-8
 * (`MAX_NAME_BYTES` in server/src/service/limits.rs). */
export const MAX_NAME_BYTES = 256;

/** `name` cut to at most MAX_NAME_BYTES bytes of UTF-8, at a character's
 * boundary (never in the middle of one, nor of a surrogate pair). */
export function fitName(name: string): string {
  const encoder = new TextEncoder();
  if (encoder.encode(name).length <= MAX_NAME_BYTES) return name;
  let bytes = 0;
  let out = "";
  for (const ch of name) {
    bytes += encoder.encode(ch).length;
    if (bytes > MAX_NAME_BYTES) break;
    out += ch;
  }
  return out;
}

/** This tab's name, as kept: trimmed and cut to fit; "" when none. A tab that
 * has none yet takes the last name given in this browser, and keeps it: a name
 * given in another tab later does not change it. */
export function givenName(): string {
  const mine = sessionStorage.getItem(KEY);
  if (mine !== null) return mine;
  const last = localStorage.getItem(KEY) ?? "";
  sessionStorage.setItem(KEY, last);
  return last;
}

/** Keeps `name` (trimmed, cut to fit; empty: none) as this tab's name and as the
 * last one given in this browser, and returns what was kept. */
export function setGivenName(name: string): string {
  const kept = fitName(name.trim()).trimEnd();
  // "" is kept in the tab too: emptied, it stays empty across a reload.
  sessionStorage.setItem(KEY, kept);
  if (kept) localStorage.setItem(KEY, kept);
  else localStorage.removeItem(KEY);
  return kept;
}

/** The name to join with. */
export function clientName(): string {
  return givenName() || DEFAULT_NAME;
}

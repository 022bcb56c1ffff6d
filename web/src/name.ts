// The name a browser station joins with (Station.Attach's client_name), which the
// sessions table shows beside its station id: what the trainee gave in the live
// page, kept in the browser (localStorage) across reloads and sessions;
// "browser console" when none is given.

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

/** The name given, as kept: trimmed and cut to fit; "" when none. */
export function givenName(): string {
  return localStorage.getItem(KEY) ?? "";
}

/** Keeps `name` (trimmed, cut to fit; empty: none) and returns what was kept. */
export function setGivenName(name: string): string {
  const kept = fitName(name.trim()).trimEnd();
  if (kept) localStorage.setItem(KEY, kept);
  else localStorage.removeItem(KEY);
  return kept;
}

/** The name to join with. */
export function clientName(): string {
  return givenName() || DEFAULT_NAME;
}

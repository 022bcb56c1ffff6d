// What the page tells the person: the connection state in the header (also as
// data-state, which the browser tests read) and a notice line.
export type ConnectionState = "idle" | "connecting" | "live" | "reconnecting" | "error" | "ended";

export function setConnection(state: ConnectionState, detail = ""): void {
  const el = document.getElementById("connection")!;
  el.dataset.state = state;
  el.textContent = detail ? `${state}: ${detail}` : state;
}

export function notice(text: string | null): void {
  const el = document.getElementById("notice")!;
  el.hidden = !text;
  el.textContent = text ?? "";
}

/** Clears the notice if it still says `text`: not another's said since. */
export function clearNotice(text: string): void {
  if (document.getElementById("notice")!.textContent === text) notice(null);
}

/** Backoff before reconnecting: 0.5 s doubling to 10 s. */
export function backoff(attempt: number): number {
  return Math.min(10_000, 500 * 2 ** Math.min(attempt, 5));
}

export function el<K extends keyof HTMLElementTagNameMap>(
  tag: K,
  attrs: Record<string, string> = {},
  ...children: (Node | string)[]
): HTMLElementTagNameMap[K] {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
  e.append(...children);
  return e;
}

export function sleep(ms: number, signal: AbortSignal): Promise<void> {
  return new Promise((resolve) => {
    const t = setTimeout(resolve, ms);
    signal.addEventListener("abort", () => {
      clearTimeout(t);
      resolve();
    });
  });
}

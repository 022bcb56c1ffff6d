// The bearer token: asked once (the header's field), kept for the tab's life.
const KEY = "laparo.token";

export function token(): string {
  return sessionStorage.getItem(KEY) ?? "";
}

export function setToken(t: string): void {
  if (t) sessionStorage.setItem(KEY, t);
  else sessionStorage.removeItem(KEY);
}

// The console's gRPC-web clients: the laparo.v1 contract over @connectrpc's
// gRPC-web transport, to the server the page came from, with the bearer token.
import { Code, ConnectError, createClient, type Interceptor, type Transport } from "@connectrpc/connect";
import { createGrpcWebTransport } from "@connectrpc/connect-web";
import { Observe, Recordings, Scenes, Sessions, Station } from "./gen/laparo/v1/services_pb";
import { token } from "./token";

const bearer: Interceptor = (next) => async (req) => {
  const t = token();
  if (t) req.header.set("authorization", `Bearer ${t}`);
  return next(req);
};

const grpcWeb = createGrpcWebTransport({
  baseUrl: location.origin,
  interceptors: [bearer],
});

/** Deadline of a unary call, ms. Over plain http a browser holds at most six
 * connections per server, and each open stream (a live view, a replay) takes
 * one: past five views a call waits for a connection, and would wait silently
 * forever. With the deadline it fails and is said. Streams have none: they
 * last as long as the view. */
export const UNARY_TIMEOUT_MS = 10_000;

const transport: Transport = {
  unary: (method, signal, timeoutMs, header, input, contextValues) =>
    grpcWeb.unary(method, signal, timeoutMs ?? UNARY_TIMEOUT_MS, header, input, contextValues),
  stream: (method, signal, timeoutMs, header, input, contextValues) => grpcWeb.stream(method, signal, timeoutMs, header, input, contextValues),
};

export const scenes = createClient(Scenes, transport);
export const sessions = createClient(Sessions, transport);
export const station = createClient(Station, transport);
export const observe = createClient(Observe, transport);
export const recordings = createClient(Recordings, transport);

/** What went wrong with a call, in words, and whether retrying can help. */
export interface Failure {
  code: Code | undefined;
  text: string;
  /** Trying again later can help: the server is gone or restarting, or the
   * instrument asked for is held by another station. */
  retry: boolean;
  /** The token is wrong or missing. */
  auth: boolean;
  /** The server refuses the name the page was opened by (its guard against DNS
   * rebinding, on a server without tokens): no token helps, another address does. */
  host?: boolean;
  /** An instructor evicted the station: it must not join again by itself. */
  evicted?: boolean;
}

/** What connect says when a call's own deadline (timeoutMs) passes. */
const CLIENT_TIMEOUT = "the operation timed out";

/** The header by which the server marks its refusal of the page's host
 * (`server/src/console/host.rs`, `REFUSAL_HEADER`). */
const REFUSAL_HEADER = "laparo-refusal";

export function failure(e: unknown): Failure {
  if (e instanceof DOMException && e.name === "AbortError") {
    return { code: Code.Canceled, text: "cancelled", retry: false, auth: false };
  }
  const err = ConnectError.from(e);
  const text = err.rawMessage || Code[err.code] || String(e);
  if (err.metadata.get(REFUSAL_HEADER) === "host") {
    return { code: err.code, text: `this page's address is refused: ${text}`, retry: false, auth: false, host: true };
  }
  switch (err.code) {
    case Code.Unauthenticated:
      return { code: err.code, text: `wrong or missing token: ${text}`, retry: false, auth: true };
    case Code.PermissionDenied:
      return { code: err.code, text: `not allowed with this token: ${text}`, retry: false, auth: true };
    case Code.NotFound:
      return { code: err.code, text: `not found: ${text}`, retry: false, auth: false };
    case Code.AlreadyExists:
      // An instrument another station holds (the server's only use of the code):
      // it is free again when that station leaves, or, if its page went away,
      // once the server sees it gone; worth waiting for.
      return { code: err.code, text: `${text}; waiting for its release`, retry: true, auth: false };
    case Code.Aborted:
      // An instructor evicted the station (the server's only use of the code;
      // its text says by whom and why): joining again would undo the eviction.
      return { code: err.code, text, retry: false, auth: false, evicted: true };
    case Code.DeadlineExceeded:
      // A unary call past UNARY_TIMEOUT_MS (no connection free, say): the
      // client's own deadline, whose message is connect's. Otherwise the server
      // ended the stream for its station timeout, and its text says why.
      if (err.rawMessage === CLIENT_TIMEOUT) {
        return { code: err.code, text: `no answer within ${UNARY_TIMEOUT_MS / 1000} s: ${text}`, retry: true, auth: false };
      }
      return { code: err.code, text: `connection lost: ${text}`, retry: true, auth: false };
    case Code.Unavailable:
    case Code.Unknown:
    case Code.Internal:
      return { code: err.code, text: `connection lost: ${text}`, retry: true, auth: false };
    default:
      return { code: err.code, text, retry: false, auth: false };
  }
}

export { Code };

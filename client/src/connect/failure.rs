//! What went wrong with a connection, in words.
//!
//! tonic reports a transport failure as a short top-level error ("transport error",
//! "h2 protocol error", "operation was canceled") whose causes hold what happened:
//! an [`io::Error`] of a kind (refused, reset, end of file), a keep-alive that timed
//! out, or a peer that is not HTTP/2 at all. These functions walk the chain of
//! causes ([`std::error::Error::source`], and the payload of each `io::Error`, which
//! `source` skips) and say what the user can act on.

use std::error::Error;

use std::io;

use tonic::Status;

/// The causes of `error`, itself first; an `io::Error`'s payload is visited too.
pub fn causes<'a>(error: &'a (dyn Error + 'static)) -> Vec<&'a (dyn Error + 'static)> {
    let mut out = Vec::new();
    let mut next = Some(error);
    while let Some(e) = next {
        out.push(e);
        next = match e.downcast_ref::<io::Error>().and_then(|io| io.get_ref()) {
            Some(inner) => Some(inner as &(dyn Error + 'static)),
            None => e.source(),
        };
        if out.len() > 32 {
            break;
        }
    }
    out
}

/// An error and its causes, joined with `: `, each said once.
pub fn error_chain(error: &(dyn Error + 'static)) -> String {
    let mut out = String::new();
    for e in causes(error) {
        let s = e.to_string();
        if !out.contains(&s) {
            if !out.is_empty() {
                out.push_str(": ");
            }
            out.push_str(&s);
        }
    }
    out
}

/// The first `io::Error` kind among the causes of `error`, if any.
pub fn io_kind(error: &(dyn Error + 'static)) -> Option<io::ErrorKind> {
    causes(error)
        .into_iter()
        .find_map(|e| e.downcast_ref::<io::Error>().map(io::Error::kind))
}

/// What a peer that does not speak what was expected answered, from the first bytes
/// it sent; `None` when they look right (or nothing came).
///
/// Over plain HTTP/2 a server's first frame is its SETTINGS (frame type 4, the
/// fourth byte of the 9-byte frame header, RFC 9113 §3.4). An HTTP/1 server answers
/// the HTTP/2 preface with a status line; a TLS server with a record whose first
/// byte is 0x15 (alert) or 0x16 (handshake) and second 0x03 (TLS 1.x). Under TLS
/// (`tls`) only the raw status line of a plain HTTP server can be recognised.
pub fn peer_answer(first: &[u8], tls: bool) -> Option<String> {
    if first.starts_with(b"HTTP/") {
        let line = first
            .split(|&b| b == b'\r' || b == b'\n')
            .next()
            .unwrap_or(first);
        return Some(format!("{} …", printable(line)));
    }
    if tls || first.is_empty() {
        return None;
    }
    if first.len() >= 2 && (first[0] == 0x15 || first[0] == 0x16) && first[1] == 0x03 {
        return Some("with TLS: use an https URL".into());
    }
    if first.len() >= 4 && first[3] != 0x04 {
        return Some(format!("bytes that are not HTTP/2: {}", printable(first)));
    }
    None
}

/// Words for a TLS handshake that failed on the server's certificate, from the
/// error chain's text (`detail`): rustls names the fault by its Rust name
/// (`invalid peer certificate: UnknownIssuer`), which says little to an operator.
/// `None` for any other failure.
pub fn certificate_words(detail: &str) -> Option<&'static str> {
    const FAULTS: [(&str, &str); 6] = [
        (
            "CaUsedAsEndEntity",
            "the server presents a CA certificate (CA:TRUE) as its own, which TLS \
             clients refuse: give the server a certificate signed by that CA, not the \
             CA itself",
        ),
        (
            "UnknownIssuer",
            "the server's certificate is not signed by the CA certificate given (--ca)",
        ),
        (
            "NotValidForName",
            "the server's certificate does not name the host of the URL (its subject \
             alternative names)",
        ),
        ("Expired", "the server's certificate has expired"),
        (
            "NotValidYet",
            "the server's certificate is not valid yet (is this machine's clock right?)",
        ),
        ("Revoked", "the server's certificate is revoked"),
    ];
    if !detail.contains("invalid peer certificate") {
        return None;
    }
    FAULTS
        .iter()
        .find(|(name, _)| detail.contains(name))
        .map(|&(_, words)| words)
}

/// `bytes` as text, anything but printable ASCII escaped.
fn printable(bytes: &[u8]) -> String {
    bytes.escape_ascii().to_string()
}

/// Words for a gRPC status made on this side because the transport failed (the
/// server died, closed the connection, stopped answering); `None` for a status the
/// server sent, which says what it means itself.
pub fn lost(status: &Status) -> Option<String> {
    let source = status.source()?;
    let text = error_chain(source).to_lowercase();
    let kind = io_kind(source);
    let timed_out = causes(source)
        .iter()
        .any(|e| e.downcast_ref::<tonic::TimeoutExpired>().is_some());
    Some(if timed_out {
        "no answer from the server within the call's time limit".into()
    } else if text.contains("keep-alive timed out") || text.contains("keep alive timed out") {
        "the server stopped answering (no reply to a keep-alive ping)".into()
    } else if kind == Some(io::ErrorKind::ConnectionRefused) || text.contains("connection refused")
    {
        "the server no longer accepts connections (connection refused): did it stop?".into()
    } else if matches!(
        kind,
        Some(
            io::ErrorKind::ConnectionReset
                | io::ErrorKind::ConnectionAborted
                | io::ErrorKind::BrokenPipe
                | io::ErrorKind::UnexpectedEof
        )
    ) || [
        "reset",
        "broken pipe",
        "eof",
        "end of file",
        "closed",
        "error reading a body",
    ]
    .iter()
    .any(|w| text.contains(w))
    {
        CLOSED.into()
    } else {
        format!("the connection failed: {}", error_chain(source))
    })
}

/// What [`lost`] says of a connection the server closed (or that broke).
/// A server that stops closes its connections; so does one that ends a stream its
/// client left unread for its `--station-timeout` (a client suspended, or too busy
/// to read), which that client, frozen meanwhile, cannot tell apart.
const CLOSED: &str = "the server closed the connection: did it stop, or end this stream \
                      because it went unread for the server's --station-timeout?";

/// [`lost`] for a stream that had heard nothing from the server for `silent`.
///
/// A keep-alive that timed out reaches the stream as a broken pipe, the same words
/// as a server that closed its socket. A server that closes its socket is noticed
/// at once, while one that stopped answering (stopped, hung, cut off) is noticed
/// only when the keep-alive gives up, at least
/// [`KEEPALIVE_INTERVAL`](super::KEEPALIVE_INTERVAL) after the last byte came; and
/// the streams of a session carry a frame every tick. So a stream that broke after
/// that long a silence was ended by the keep-alive.
pub fn lost_after(status: &Status, silent: std::time::Duration) -> Option<String> {
    let words = lost(status)?;
    if silent >= super::KEEPALIVE_INTERVAL && words == CLOSED {
        return Some(format!(
            "the server stopped answering: nothing came for {:.0} s and a keep-alive ping \
             got no reply",
            silent.as_secs_f64()
        ));
    }
    Some(words)
}

/// A status as words: [`lost`] for a transport failure, the server's code and
/// message otherwise.
pub fn describe_status(status: &Status) -> String {
    lost(status).unwrap_or_else(|| {
        format!(
            "the server answered {}: {}",
            code_name(status.code()),
            status.message()
        )
    })
}

/// The name of a gRPC status code as the gRPC specification spells it
/// (`INVALID_ARGUMENT`), where its `Debug` form reads `InvalidArgument`.
pub fn code_name(code: tonic::Code) -> &'static str {
    use tonic::Code::*;
    match code {
        Ok => "OK",
        Cancelled => "CANCELLED",
        Unknown => "UNKNOWN",
        InvalidArgument => "INVALID_ARGUMENT",
        DeadlineExceeded => "DEADLINE_EXCEEDED",
        NotFound => "NOT_FOUND",
        AlreadyExists => "ALREADY_EXISTS",
        PermissionDenied => "PERMISSION_DENIED",
        ResourceExhausted => "RESOURCE_EXHAUSTED",
        FailedPrecondition => "FAILED_PRECONDITION",
        Aborted => "ABORTED",
        OutOfRange => "OUT_OF_RANGE",
        Unimplemented => "UNIMPLEMENTED",
        Internal => "INTERNAL",
        Unavailable => "UNAVAILABLE",
        DataLoss => "DATA_LOSS",
        Unauthenticated => "UNAUTHENTICATED",
    }
}

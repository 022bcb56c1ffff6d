//! Text from files and clients made safe to print.
//!
//! Names, ids, reasons and file names reach the server from clients and from files
//! in its directories; the server puts them in statuses, events and listings, and
//! clients print those in terminals. A control character in such text can move the
//! cursor, clear the screen or set a window title (ESC `[`…, the 8-bit CSI U+009B,
//! OSC sequences ending in BEL), and a bidirectional override can make the text read
//! as something else than it is. [`printable`] replaces each of those characters by
//! its escape, so the text shows what it holds and does nothing to the terminal.
//!
//! Numbers a client sends are echoed in the statuses that refuse them; [`Number`]
//! keeps such an echo short whatever the number (`1e300`, not 301 digits).

use std::borrow::Cow;

/// Whether `c` must not reach a terminal as it is: the C0 controls (U+0000–U+001F,
/// tab and newline among them: one message stays on one line), DEL, the C1 controls
/// (U+0080–U+009F, which some terminals take as ESC sequences), and the Unicode
/// bidirectional embeddings, overrides and isolates (U+202A–U+202E, U+2066–U+2069),
/// which reorder what follows them when displayed.
pub fn needs_escape(c: char) -> bool {
    c.is_control() || matches!(c, '\u{202a}'..='\u{202e}' | '\u{2066}'..='\u{2069}')
}

/// `text` with every character [`needs_escape`] names written as its Rust escape
/// (`\n`, `\t`, `\u{1b}`, `\u{202e}`); borrowed, without copying, when it has none.
/// Everything else (any script, emoji, a backslash) is kept as it is: the point is
/// that nothing printed acts on a terminal, not that the text round-trips.
pub fn printable(text: &str) -> Cow<'_, str> {
    if !text.chars().any(needs_escape) {
        return Cow::Borrowed(text);
    }
    let mut out = String::with_capacity(text.len() + 8);
    for c in text.chars() {
        if needs_escape(c) {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    Cow::Owned(out)
}

/// An `f64` written in its shortest form that reads back as the same number, in
/// decimal notation (`0.25`, `1500`) within `[1e-5, 1e16)` in magnitude and for
/// zero, in scientific notation (`1e300`, `-2.5e-7`) outside it, `NaN` and `inf` as
/// Rust writes them. Plain `{}` writes `1e300` as 301 digits and `1e-300` with 300
/// zeros; this is never longer than 24 characters (`-2.2250738585072014e-308`).
#[derive(Clone, Copy, Debug)]
pub struct Number(pub f64);

impl std::fmt::Display for Number {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let x = self.0;
        let magnitude = x.abs();
        if x == 0.0 || !x.is_finite() || (1e-5..1e16).contains(&magnitude) {
            write!(f, "{x}")
        } else {
            write!(f, "{x:e}")
        }
    }
}

#[cfg(test)]
mod tests;

//! Text from files and clients made safe to print.
//!
//! Names, ids, reasons and file names reach the server from clients and from files
//! in its directories; the server puts them in statuses, events and listings, and
//! clients print those in terminals. A control character in such text can move the
//! cursor, clear the screen or set a window title (ESC `[`…, the 8-bit CSI U+009B,
//! OSC sequences ending in BEL), and a bidirectional override can make the text read
//! as something else than it is. [`printable`] replaces each of those characters by
//! its escape, so the text shows what it holds and does nothing to the terminal.

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

#[cfg(test)]
mod tests;

use std::borrow::Cow;

use proptest::prelude::*;

use super::{needs_escape, printable};

#[test]
fn plain_text_of_any_script_is_borrowed_as_it_is() {
    for s in [
        "",
        "liver-20k",
        "s1-default-1764000000.mcap",
        "Élève 学生 🫀",
        r"a\b",
    ] {
        assert!(matches!(printable(s), Cow::Borrowed(b) if b == s), "{s:?}");
    }
}

#[test]
fn terminal_controls_are_written_as_escapes() {
    let cases = [
        (
            "\u{1b}[2J\u{1b}]0;owned\u{7}",
            r"\u{1b}[2J\u{1b}]0;owned\u{7}",
        ),
        ("a\nb\tc\rd", r"a\nb\tc\rd"),
        ("csi\u{9b}31m", r"csi\u{9b}31m"),
        ("del\u{7f}", r"del\u{7f}"),
        ("nul\0", r"nul\u{0}"),
        ("evil\u{202e}gpj.mcap", r"evil\u{202e}gpj.mcap"),
        ("iso\u{2066}x\u{2069}", r"iso\u{2066}x\u{2069}"),
    ];
    for (raw, shown) in cases {
        assert_eq!(printable(raw), shown, "{raw:?}");
    }
}

proptest! {
    /// Whatever the input, the output holds no character a terminal acts on, and
    /// input without one comes back unchanged.
    #[test]
    fn output_never_holds_a_control(s in any::<String>()) {
        let out = printable(&s);
        prop_assert!(!out.chars().any(needs_escape), "{out:?}");
        if !s.chars().any(needs_escape) {
            prop_assert_eq!(out.as_ref(), s.as_str());
        } else {
            prop_assert!(out.len() > s.len());
        }
    }
}

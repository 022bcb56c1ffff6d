use std::borrow::Cow;

use proptest::prelude::*;

use super::{Number, needs_escape, printable};

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

#[test]
fn numbers_are_written_plainly_in_range_and_short_outside_it() {
    let cases = [
        (0.0, "0"),
        (-0.0, "-0"),
        (1.5, "1.5"),
        (604_800.0, "604800"),
        (3.999_999_999_999_990_7, "3.9999999999999907"),
        (1e-5, "0.00001"),
        (9.9e-6, "9.9e-6"),
        (1e16, "1e16"),
        (1e300, "1e300"),
        (-1e-300, "-1e-300"),
        (f64::MAX, "1.7976931348623157e308"),
        (f64::INFINITY, "inf"),
        (f64::NEG_INFINITY, "-inf"),
        (f64::NAN, "NaN"),
    ];
    for (x, shown) in cases {
        assert_eq!(Number(x).to_string(), shown, "{x:?}");
    }
}

proptest! {
    /// Any `f64` is written in at most 24 characters that read back as itself.
    #[test]
    fn a_number_reads_back_as_itself_in_at_most_24_characters(
        bits in prop_oneof![any::<u64>(), (-1e17..1e17f64).prop_map(f64::to_bits)]
    ) {
        let x = f64::from_bits(bits);
        let shown = Number(x).to_string();
        prop_assert!(shown.len() <= 24, "{shown}");
        let back: f64 = shown.parse().unwrap();
        prop_assert!(back.to_bits() == bits || (x.is_nan() && back.is_nan()), "{shown}");
    }
}

//! The idle timeout a client or operator gives a session, in seconds.

use std::time::Duration;

use laparo_proto::text::Number;

/// Longest idle timeout, s: 7 days. A session nobody has joined for a week is
/// forgotten, and 0 already means "never". The bound also keeps the duration far from
/// what `Duration` and `Instant` arithmetic can hold (about 1.8·10¹⁹ s), where
/// converting it would panic.
pub const MAX_IDLE_TIMEOUT_S: f64 = 7.0 * 24.0 * 3600.0;

/// Reads an idle timeout of `seconds`: 0 is "never" (`None`), otherwise it must be
/// finite and within (0, [`MAX_IDLE_TIMEOUT_S`]]. The error states the range; the
/// caller names the field.
pub fn idle_timeout(seconds: f64) -> Result<Option<Duration>, String> {
    if seconds == 0.0 {
        Ok(None)
    } else if seconds.is_finite() && seconds > 0.0 && seconds <= MAX_IDLE_TIMEOUT_S {
        Ok(Some(Duration::from_secs_f64(seconds)))
    } else {
        Err(format!(
            "{} s is outside [0, {MAX_IDLE_TIMEOUT_S}] s (0: never; at most 7 days)",
            Number(seconds)
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn idle_timeouts_within_the_range_pass_and_others_are_refused() {
        assert_eq!(idle_timeout(0.0), Ok(None));
        assert_eq!(idle_timeout(1.5), Ok(Some(Duration::from_millis(1500))));
        assert_eq!(
            idle_timeout(MAX_IDLE_TIMEOUT_S),
            Ok(Some(Duration::from_secs(604_800)))
        );
        for bad in [
            -1.0,
            -0.0 - f64::MIN_POSITIVE,
            MAX_IDLE_TIMEOUT_S * (1.0 + f64::EPSILON),
            1.85e19,
            1e20,
            f64::MAX,
            f64::INFINITY,
            f64::NAN,
        ] {
            let message = idle_timeout(bad).unwrap_err();
            assert!(message.contains("[0, 604800] s"), "{bad}: {message}");
        }
        // Echoed in its short form (`1e300`, not 301 digits).
        let message = idle_timeout(1e300).unwrap_err();
        assert!(message.starts_with("1e300 s is outside"), "{message}");
    }
}

//! The gRPC framing of a request body, read as it passes, to tell when a second
//! message begins in a call that sends one.
//!
//! A gRPC body is a sequence of messages, each a flag byte (compressed or not), a
//! 4-byte big-endian length `n`, then `n` bytes; the HTTP body's data frames cut
//! it anywhere, a prefix included. tonic serves a unary or server-streaming call
//! with its first message and reads the rest of the body only to drop it, so a
//! client that sent two (a client built for a stream, or a broken one) got an
//! answer to the first as if all was well. gRPC's own servers answer such a call
//! `INTERNAL` ("more than one request message for a unary call"), and so does this
//! server, naming it.

/// Bytes before a message's contents: its flag and its length.
const PREFIX: usize = 5;

/// Where a body's framing stands (see the module).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Framing {
    /// The prefix being read, and how many of its bytes have come.
    prefix: [u8; PREFIX],
    have: usize,
    /// Bytes of the current message still to come.
    remaining: u64,
    /// Whether a message has begun (its first byte read).
    begun: bool,
}

impl Framing {
    /// Reads the next bytes of the body; false once a second message has begun
    /// (what comes after is not read).
    pub(super) fn read(&mut self, mut data: &[u8]) -> bool {
        while !data.is_empty() {
            if self.remaining > 0 {
                let n = data
                    .len()
                    .min(usize::try_from(self.remaining).unwrap_or(usize::MAX));
                self.remaining -= n as u64;
                data = &data[n..];
                continue;
            }
            if self.have == 0 {
                if self.begun {
                    return false;
                }
                self.begun = true;
            }
            let n = data.len().min(PREFIX - self.have);
            self.prefix[self.have..self.have + n].copy_from_slice(&data[..n]);
            self.have += n;
            data = &data[n..];
            if self.have == PREFIX {
                let [_, a, b, c, d] = self.prefix;
                self.remaining = u64::from(u32::from_be_bytes([a, b, c, d]));
                self.have = 0;
            }
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A message of `n` bytes with its prefix.
    fn message(n: u32) -> Vec<u8> {
        let mut m = vec![0];
        m.extend_from_slice(&n.to_be_bytes());
        m.extend(std::iter::repeat_n(7, n as usize));
        m
    }

    #[test]
    fn one_message_passes_however_it_is_cut_and_a_second_is_found_at_its_first_byte() {
        for (first, second) in [(0, 0), (1, 3), (300, 0), (70_000, 12)] {
            let one = message(first);
            let mut two = one.clone();
            two.extend(message(second));
            // Cut into chunks of every size from 1 byte to the whole body.
            for chunk in [1, 2, 4, 5, 6, 7, 1000, two.len()] {
                let mut framing = Framing::default();
                assert!(
                    one.chunks(chunk).all(|c| framing.read(c)),
                    "one message of {first} bytes, chunks of {chunk}"
                );
                let mut framing = Framing::default();
                let mut read = 0;
                let refused = two.chunks(chunk).find_map(|c| {
                    read += c.len();
                    (!framing.read(c)).then_some(read)
                });
                // Refused in the chunk that holds the second message's first byte.
                let at = one.len() + 1;
                assert_eq!(
                    refused,
                    Some(at.div_ceil(chunk) * chunk).map(|r| r.min(two.len())),
                    "two messages of {first} and {second} bytes, chunks of {chunk}"
                );
            }
        }
    }

    #[test]
    fn an_empty_body_and_a_cut_prefix_are_not_a_second_message() {
        let mut framing = Framing::default();
        assert!(framing.read(&[]));
        assert!(framing.read(&[0, 0, 0]));
        assert!(framing.read(&[0, 2, 9]));
        assert!(framing.read(&[9]));
        assert!(!framing.read(&[0]));
    }
}

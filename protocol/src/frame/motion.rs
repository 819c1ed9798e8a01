//! The motion of held bodies in a delta frame: one residual per axis and body, range-coded.
//!
//! A receiver moves every body it holds one frame on, `p += d`, and the frame then gives,
//! for each body and axis, how many [`POS_STEP`](super::POS_STEP)s the truth is from
//! that prediction (`r`, rounded to the nearest); the receiver adds `r` steps to both `p`
//! and `d`. So a receiver's position is within half a step of the truth (1/2048 units)
//! at every frame, and its `d` is what its position moved over the frame. A body at
//! rest or in steady motion has residuals of 0; falling, a residual that repeats.
//!
//! # The coder
//!
//! An adaptive binary range coder, LZMA's: a 32-bit `range` (starting at 2^32 - 1) and
//! 11-bit probabilities of a 0 (starting at 1024 of 2048). A bit coded with probability
//! `p` splits the range at `bound = (range >> 11) * p`: a 0 keeps the part below (`range =
//! bound`, `p += (2048 - p) >> 5`), a 1 the part above (`code -= bound; range -= bound`,
//! `p -= p >> 5`). A bit at even odds halves the range (`range >>= 1`, a 1 above it).
//! While `range < 2^24`, it and `code` shift left a byte, `code` taking the next byte.
//! The decoder's `code` starts as the first four bytes, big-endian; past the end of the
//! stream it reads zeros, and a stream it does not read to the end is refused. (The
//! encoder ends on the value of the final range with the most trailing zero bits, drops
//! LZMA's first byte, always 0, and the trailing zero bytes.) The probabilities start
//! afresh in every frame, so a frame needs nothing of the frames before it but the state
//! it follows.
//!
//! # What is coded
//!
//! Per body held, in increasing key order: x's residual, y's, then whether the collided
//! flag changed (probability by what the flag was: 2 contexts). A residual, on axis `a`
//! (0 x, 1 y), given the body's `d` on that axis before the frame (`speed`: 0 when `d` is
//! 0, 1 when `|d|` is at most 3 steps, else 2) and the residual on that axis of the body
//! coded before it in the frame (`near`: `min(|r|, 2)`, 0 for the first):
//! - `r != 0`, in context `[a][speed][near]`; nothing more when 0;
//! - `r < 0`, in context `[a][sign of d + 1]`;
//! - `k`, the index of the highest set bit of `|r|` (0 to 62), in unary: a 1 for each
//!   `j < k` and a 0, each in context `[a][speed][min(j, 15)]`, the 0 left out at 62;
//! - the `k` bits of `|r|` below its highest, high first: the first in context
//!   `[a][min(k, 15)][0]`, the second in `[a][min(k, 15)][1 + the first]`, the rest at
//!   even odds.
//!
//! Neighbours in a pile or a falling row move together, so a residual like the one before
//! it, and a body at rest after bodies at rest, cost a small fraction of a bit.

use super::DecodeError;

/// Bits of a probability.
const PROB_BITS: u32 = 11;
const PROB_ONE: u16 = 1 << PROB_BITS;
/// A probability moves 1/2^MOVE_BITS of the way to each bit it sees.
const MOVE_BITS: u32 = 5;
const TOP: u32 = 1 << 24;
/// The highest `k` of a residual: `|r|` below 2^63.
const MAX_CLASS: u32 = 62;
/// Unary positions with contexts of their own; higher ones share the last.
const CLASS_CONTEXTS: usize = 16;

/// Writes bits, each at the odds its probability gives, and adapts the probability.
pub(super) struct RangeEncoder {
    low: u64,
    range: u32,
    cache: u8,
    pending: u64,
    out: Vec<u8>,
}

impl RangeEncoder {
    pub fn new() -> Self {
        RangeEncoder {
            low: 0,
            range: u32::MAX,
            cache: 0,
            pending: 1,
            out: Vec::new(),
        }
    }

    fn shift_low(&mut self) {
        if (self.low as u32) < 0xFF00_0000 || (self.low >> 32) != 0 {
            let carry = (self.low >> 32) as u8;
            let mut byte = self.cache;
            loop {
                self.out.push(byte.wrapping_add(carry));
                byte = 0xFF;
                self.pending -= 1;
                if self.pending == 0 {
                    break;
                }
            }
            self.cache = (self.low >> 24) as u8;
        }
        self.pending += 1;
        self.low = (self.low & 0x00FF_FFFF) << 8;
    }

    fn normalize(&mut self) {
        while self.range < TOP {
            self.range <<= 8;
            self.shift_low();
        }
    }

    /// The coded bytes: the value in the final interval with the most trailing zero
    /// bits, without its first byte (always 0) and its trailing zero bytes (a decoder
    /// reads zeros past the end).
    pub fn finish(mut self) -> Vec<u8> {
        let last = self.low + self.range as u64 - 1;
        for k in (0..=32).rev() {
            let v = last & !((1u64 << k) - 1);
            if v >= self.low {
                self.low = v;
                break;
            }
        }
        for _ in 0..5 {
            self.shift_low();
        }
        debug_assert_eq!(self.out[0], 0);
        self.out.remove(0);
        while self.out.last() == Some(&0) {
            self.out.pop();
        }
        self.out
    }
}

/// Reads what a [`RangeEncoder`] wrote, and zeros past the end of it.
pub(super) struct RangeDecoder<'a> {
    code: u32,
    range: u32,
    bytes: &'a [u8],
    at: usize,
}

impl<'a> RangeDecoder<'a> {
    pub fn new(bytes: &'a [u8]) -> Self {
        let mut d = RangeDecoder {
            code: 0,
            range: u32::MAX,
            bytes,
            at: 0,
        };
        for _ in 0..4 {
            d.code = (d.code << 8) | d.next() as u32;
        }
        d
    }

    fn next(&mut self) -> u8 {
        let b = self.bytes.get(self.at).copied().unwrap_or(0);
        self.at += 1;
        b
    }

    fn normalize(&mut self) {
        while self.range < TOP {
            self.range <<= 8;
            self.code = (self.code << 8) | self.next() as u32;
        }
    }

    /// Refuses a stream with bytes its decoding did not read.
    pub fn finish(self) -> Result<(), DecodeError> {
        if self.at < self.bytes.len() {
            return Err(DecodeError::Malformed(format!(
                "motion of {} bytes, {} of them unread",
                self.bytes.len(),
                self.bytes.len() - self.at
            )));
        }
        Ok(())
    }
}

/// One side of the coder: the encoder writes the bit it is given and returns it, the
/// decoder returns the bit it reads. One binarisation ([`Model`]) drives both.
pub(super) trait Coder {
    fn bit(&mut self, prob: &mut u16, bit: bool) -> bool;
    /// A bit at even odds.
    fn even(&mut self, bit: bool) -> bool;
}

fn adapt(prob: &mut u16, bit: bool) {
    if bit {
        *prob -= *prob >> MOVE_BITS;
    } else {
        *prob += (PROB_ONE - *prob) >> MOVE_BITS;
    }
}

impl Coder for RangeEncoder {
    fn bit(&mut self, prob: &mut u16, bit: bool) -> bool {
        let bound = (self.range >> PROB_BITS) * *prob as u32;
        if bit {
            self.low += bound as u64;
            self.range -= bound;
        } else {
            self.range = bound;
        }
        adapt(prob, bit);
        self.normalize();
        bit
    }

    fn even(&mut self, bit: bool) -> bool {
        self.range >>= 1;
        if bit {
            self.low += self.range as u64;
        }
        self.normalize();
        bit
    }
}

impl Coder for RangeDecoder<'_> {
    fn bit(&mut self, prob: &mut u16, _: bool) -> bool {
        let bound = (self.range >> PROB_BITS) * *prob as u32;
        let bit = self.code >= bound;
        if bit {
            self.code -= bound;
            self.range -= bound;
        } else {
            self.range = bound;
        }
        adapt(prob, bit);
        self.normalize();
        bit
    }

    fn even(&mut self, _: bool) -> bool {
        self.range >>= 1;
        let bit = self.code >= self.range;
        if bit {
            self.code -= self.range;
        }
        self.normalize();
        bit
    }
}

/// How fast a body moves on an axis, in position steps a frame: 0, within 3, beyond.
fn speed_class(d: i64, step: i64) -> usize {
    match d.unsigned_abs() {
        0 => 0,
        v if v <= 3 * step.unsigned_abs() => 1,
        _ => 2,
    }
}

/// The probabilities of one frame's motion section.
pub(super) struct Model {
    zero: [[[u16; 3]; 3]; 2],
    sign: [[u16; 3]; 2],
    class: [[[u16; CLASS_CONTEXTS]; 3]; 2],
    /// The first bit below the highest, and the second given the first.
    low: [[[u16; 3]; CLASS_CONTEXTS]; 2],
    collided: [u16; 2],
    /// The residual of the body before, on each axis.
    before: [i64; 2],
}

impl Model {
    pub fn new() -> Self {
        let half = PROB_ONE / 2;
        Model {
            zero: [[[half; 3]; 3]; 2],
            sign: [[half; 3]; 2],
            class: [[[half; CLASS_CONTEXTS]; 3]; 2],
            low: [[[half; 3]; CLASS_CONTEXTS]; 2],
            collided: [half; 2],
            before: [0; 2],
        }
    }

    /// Codes one body's residuals (`r`, ignored by a decoder) given its displacement
    /// `d` in [`FINE`](super::FINE) units and `step`, the position step; returns them.
    pub fn residuals<C: Coder>(
        &mut self,
        c: &mut C,
        d: [i64; 2],
        step: i64,
        r: [i64; 2],
    ) -> [i64; 2] {
        let mut out = [0; 2];
        for axis in 0..2 {
            let speed = speed_class(d[axis], step);
            let near = self.before[axis].unsigned_abs().min(2) as usize;
            let v = r[axis];
            out[axis] = if c.bit(&mut self.zero[axis][speed][near], v != 0) {
                let sign = (d[axis].signum() + 1) as usize;
                let negative = c.bit(&mut self.sign[axis][sign], v < 0);
                let u = v.unsigned_abs();
                let k_in = 63 - u.max(1).leading_zeros();
                let mut k = 0;
                while k < MAX_CLASS {
                    let slot = &mut self.class[axis][speed][(k as usize).min(CLASS_CONTEXTS - 1)];
                    if !c.bit(slot, k < k_in) {
                        break;
                    }
                    k += 1;
                }
                let mut m: u64 = 1;
                for j in (0..k).rev() {
                    let bit = (u >> j) & 1 == 1;
                    // The two bits below the highest in a context of their own (a repeated
                    // residual costs next to nothing); the rest at even odds.
                    let bit = if k - j <= 2 {
                        let top = (m as usize & 1) * usize::from(k - j == 2);
                        let slot = (k as usize).min(CLASS_CONTEXTS - 1);
                        c.bit(&mut self.low[axis][slot][(k - j) as usize - 1 + top], bit)
                    } else {
                        c.even(bit)
                    };
                    m = (m << 1) | bit as u64;
                }
                if negative {
                    -(m as i64)
                } else {
                    m as i64
                }
            } else {
                0
            };
            self.before[axis] = out[axis];
        }
        out
    }

    /// Codes whether a body's collided flag changed (`changed`, ignored by a decoder),
    /// given what it was; returns whether it did.
    pub fn collided<C: Coder>(&mut self, c: &mut C, was: bool, changed: bool) -> bool {
        c.bit(&mut self.collided[was as usize], changed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn code(bodies: &[([i64; 2], [i64; 2], bool)]) -> Vec<u8> {
        let mut e = RangeEncoder::new();
        let mut m = Model::new();
        for &(d, r, changed) in bodies {
            m.residuals(&mut e, d, 1 << 14, r);
            m.collided(&mut e, false, changed);
        }
        e.finish()
    }

    fn decode(bytes: &[u8], ds: &[[i64; 2]]) -> Result<Vec<([i64; 2], bool)>, DecodeError> {
        let mut c = RangeDecoder::new(bytes);
        let mut m = Model::new();
        let out = ds
            .iter()
            .map(|&d| {
                (
                    m.residuals(&mut c, d, 1 << 14, [0; 2]),
                    m.collided(&mut c, false, false),
                )
            })
            .collect();
        c.finish()?;
        Ok(out)
    }

    proptest! {
        #[test]
        fn what_is_coded_decodes(bodies in proptest::collection::vec(
            ((-(1i64 << 40)..(1i64 << 40), -(1i64 << 40)..(1i64 << 40)),
             (prop_oneof![Just(0i64), -3i64..3, -(1i64 << 50)..(1i64 << 50)],
              prop_oneof![Just(0i64), -3i64..3, -(1i64 << 50)..(1i64 << 50)]),
             any::<bool>()), 0..300)) {
            let bodies: Vec<_> = bodies.into_iter().map(|((dx, dy), (rx, ry), c)| ([dx, dy], [rx, ry], c)).collect();
            let bytes = code(&bodies);
            let ds: Vec<_> = bodies.iter().map(|b| b.0).collect();
            let back = decode(&bytes, &ds).unwrap();
            let want: Vec<_> = bodies.iter().map(|b| (b.1, b.2)).collect();
            prop_assert_eq!(back, want);
        }

        #[test]
        fn any_bytes_decode_to_something_or_are_refused(bytes in proptest::collection::vec(any::<u8>(), 0..64), n in 0usize..200) {
            // Never a panic, and the work is bounded by the bodies held.
            let _ = decode(&bytes, &vec![[0, 0]; n]);
        }
    }

    #[test]
    fn bodies_at_rest_cost_a_fraction_of_a_bit_each() {
        let rest = vec![([0, 0], [0, 0], false); 5000];
        let bytes = code(&rest);
        // 5000 bodies x 3 decisions near the coder's floor of odds: well under 0.02 bytes
        // each.
        assert!(bytes.len() < 100, "{} bytes", bytes.len());
        let one = code(&[([0, 0], [0, 0], false)]);
        assert!(one.len() <= 1, "{} bytes", one.len());
        assert_eq!(decode(&one, &[[0, 0]]).unwrap(), [([0, 0], false)]);
    }

    #[test]
    fn a_crowd_moving_together_costs_a_fraction_of_a_byte_each() {
        // 1000 bodies falling side by side: each the same residual as the one before.
        let falling = vec![([0, -(20 << 14)], [0, -3], false); 1000];
        let bytes = code(&falling);
        assert!(bytes.len() < 50, "{} bytes", bytes.len());
    }

    #[test]
    fn bytes_the_decoding_does_not_read_are_refused() {
        let bodies = vec![([0, -(5 << 14)], [1, -3], true); 50];
        let bytes = code(&bodies);
        let ds = vec![[0, -(5 << 14)]; 50];
        let want = vec![([1, -3], true); 50];
        assert_eq!(decode(&bytes, &ds).unwrap(), want);
        let mut padded = bytes.clone();
        padded.extend([0; 8]);
        assert!(decode(&padded, &ds).is_err());
        // Cut short, it decodes to something else (zeros are read past the end).
        assert_ne!(decode(&bytes[..bytes.len() - 1], &ds).ok(), Some(want));
    }
}

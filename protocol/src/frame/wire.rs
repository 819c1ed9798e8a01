//! Bytes in and out: LEB128 varints (signed ones zigzag-encoded), little-endian numbers,
//! length-prefixed UTF-8, and a reader that refuses what runs past the end.

use super::DecodeError;

pub(super) fn put_varint(out: &mut Vec<u8>, mut v: u64) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

pub(super) fn put_svarint(out: &mut Vec<u8>, v: i64) {
    put_varint(out, ((v << 1) ^ (v >> 63)) as u64);
}

pub(super) fn put_str(out: &mut Vec<u8>, s: &str) {
    put_varint(out, s.len() as u64);
    out.extend_from_slice(s.as_bytes());
}

/// Reads a payload front to back; every read is bounds-checked.
pub(super) struct Reader<'a> {
    pub bytes: &'a [u8],
    pub at: usize,
}

impl<'a> Reader<'a> {
    pub fn new(bytes: &'a [u8]) -> Self {
        Reader { bytes, at: 0 }
    }
    #[inline]
    pub fn take(&mut self, n: usize) -> Result<&'a [u8], DecodeError> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.bytes.len());
        let end =
            end.ok_or_else(|| DecodeError::Malformed(format!("cut short at byte {}", self.at)))?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }
    #[inline]
    pub fn u8(&mut self) -> Result<u8, DecodeError> {
        Ok(self.take(1)?[0])
    }
    #[inline]
    pub fn bytes4(&mut self) -> Result<[u8; 4], DecodeError> {
        let b = self.take(4)?;
        Ok([b[0], b[1], b[2], b[3]])
    }
    #[inline]
    pub fn u32(&mut self) -> Result<u32, DecodeError> {
        Ok(u32::from_le_bytes(self.bytes4()?))
    }
    #[inline]
    pub fn f32(&mut self) -> Result<f32, DecodeError> {
        Ok(f32::from_bits(self.u32()?))
    }
    pub fn u64(&mut self) -> Result<u64, DecodeError> {
        let b = self.take(8)?;
        let mut a = [0u8; 8];
        a.copy_from_slice(b);
        Ok(u64::from_le_bytes(a))
    }
    /// A LEB128 varint of at most 10 bytes (the bits past 64 dropped). Inlined, and its
    /// bytes read from the slice without a check each: a key frame of many particles is
    /// mostly varints.
    #[inline]
    pub fn varint(&mut self) -> Result<u64, DecodeError> {
        let mut v = 0u64;
        for (i, &b) in self.bytes[self.at..].iter().take(10).enumerate() {
            v |= ((b & 0x7f) as u64) << (7 * i);
            if b & 0x80 == 0 {
                self.at += i + 1;
                return Ok(v);
            }
        }
        Err(self.bad_varint())
    }

    /// Why the varint at `at` cannot be read: the payload ends in it, or it runs past 10
    /// bytes.
    #[cold]
    fn bad_varint(&self) -> DecodeError {
        if self.bytes.len() - self.at < 10 {
            DecodeError::Malformed(format!("cut short at byte {}", self.bytes.len()))
        } else {
            DecodeError::Malformed("varint longer than 64 bits".into())
        }
    }
    #[inline]
    pub fn svarint(&mut self) -> Result<i64, DecodeError> {
        let v = self.varint()?;
        Ok(((v >> 1) as i64) ^ -((v & 1) as i64))
    }
    pub fn str(&mut self) -> Result<String, DecodeError> {
        let n = self.varint()?;
        let n = usize::try_from(n).map_err(|_| DecodeError::Malformed("name too long".into()))?;
        let bytes = self.take(n)?;
        String::from_utf8(bytes.to_vec())
            .map_err(|_| DecodeError::Malformed("a name is not UTF-8".into()))
    }
    /// A record count, refused when the bytes left cannot hold that many records of at
    /// least `min_record` bytes: nothing is allocated for a count the payload cannot back.
    pub fn count(&mut self, min_record: usize) -> Result<usize, DecodeError> {
        let n = self.varint()?;
        let n = usize::try_from(n).unwrap_or(usize::MAX);
        if n.saturating_mul(min_record) > self.bytes.len() - self.at {
            return Err(DecodeError::Malformed(format!("{n} records cannot fit")));
        }
        Ok(n)
    }
}

//! Delta tracking, the one merge both sides of the codec share: the state receivers hold
//! (a list sorted by key) walked alongside the state now, record by record.
//!
//! A section is a count, then records in increasing key order, each starting with its
//! key's gap to the previous record's key and a flags byte. The encoder writes a record
//! for what was added, changed or removed ([`diff`]); the decoder folds records into the
//! state it holds ([`read`]). Bodies and particles differ only in what a record carries,
//! which the callers say.

use super::wire::{put_varint, Reader};
use super::{Body, DecodeError, Particle, REMOVED};

/// Something a section tracks by an increasing key.
pub(super) trait Keyed {
    fn key(&self) -> u32;
}

impl Keyed for Body {
    fn key(&self) -> u32 {
        self.key
    }
}

impl Keyed for Particle {
    fn key(&self) -> u32 {
        self.id
    }
}

/// The records of one section, being written.
pub(super) struct Records {
    bytes: Vec<u8>,
    count: u64,
    prev: u32,
}

impl Records {
    pub fn with_capacity(bytes: usize) -> Self {
        Records {
            bytes: Vec::with_capacity(bytes),
            count: 0,
            prev: 0,
        }
    }

    /// Starts the record of `key` (keys strictly increasing) and returns where its flags
    /// and payload go.
    pub fn start(&mut self, key: u32) -> &mut Vec<u8> {
        put_varint(&mut self.bytes, (key - self.prev) as u64);
        self.prev = key;
        self.count += 1;
        &mut self.bytes
    }

    /// A record saying `key` is gone.
    pub fn removed(&mut self, key: u32) {
        self.start(key).push(REMOVED);
    }

    /// Writes the section: its count, then its records.
    pub fn finish(self, out: &mut Vec<u8>) {
        put_varint(out, self.count);
        out.extend_from_slice(&self.bytes);
    }
}

/// Diffs `now` (items in increasing key order, `key` giving each one's) against `sent`,
/// what receivers were last told (same order). For every item of `now`, `record` gets
/// the receivers' version if they have one, writes whatever record it needs, and returns
/// what receivers know of the item afterwards; every item of `sent` missing from `now`
/// gets a REMOVED record. Returns what receivers know after the section.
pub(super) fn diff<T: Keyed, N>(
    sent: Vec<T>,
    now: impl IntoIterator<Item = N>,
    key: impl Fn(&N) -> u32,
    records: &mut Records,
    mut record: impl FnMut(&mut Records, Option<T>, N) -> T,
) -> Vec<T> {
    let now = now.into_iter();
    let mut told = Vec::with_capacity(now.size_hint().0);
    let mut sent = sent.into_iter().peekable();
    for item in now {
        let k = key(&item);
        while let Some(old) = sent.next_if(|s| s.key() < k) {
            records.removed(old.key());
        }
        let old = sent.next_if(|s| s.key() == k);
        told.push(record(records, old, item));
    }
    for old in sent {
        records.removed(old.key());
    }
    told
}

/// What one record does to the item of its key.
pub(super) enum Change<T> {
    /// A new item (or one sent whole again).
    New(T),
    /// The item is gone.
    Removed,
}

/// A section's records, read and checked, by kind, and the patches of the items they
/// leave (a delta's motion); each list by increasing key.
pub(super) struct Section<T, P> {
    pub news: Vec<T>,
    pub patches: Vec<(u32, P)>,
    pub removed: Vec<u32>,
}

/// Reads a section against `held` (by increasing key) without changing it: for each
/// record `parse` gets the reader at its payload, the key, the flags and the held item of
/// that key if any, checks the record against it and says what it does. Keys must
/// increase. Nothing is applied until all of a payload has been read ([`fold`]), so a
/// payload refused anywhere leaves the state as it was, and nothing held is copied.
pub(super) fn read<T: Keyed, P>(
    r: &mut Reader,
    held: &[T],
    mut parse: impl FnMut(&mut Reader, u32, u8, Option<&T>) -> Result<Change<T>, DecodeError>,
) -> Result<Section<T, P>, DecodeError> {
    // A record is at least a key gap and a flags byte.
    let n = r.count(2)?;
    let mut section = Section {
        news: Vec::new(),
        patches: Vec::with_capacity(n.min(held.len())),
        removed: Vec::new(),
    };
    let mut at = 0;
    let mut key = 0u32;
    for k in 0..n {
        let gap = u32::try_from(r.varint()?)
            .map_err(|_| DecodeError::Malformed("key gap over 32 bits".into()))?;
        if gap == 0 && k > 0 {
            return Err(DecodeError::Malformed(format!("key {key} twice")));
        }
        key = key
            .checked_add(gap)
            .ok_or_else(|| DecodeError::Malformed("key overflow".into()))?;
        while held.get(at).is_some_and(|t| t.key() < key) {
            at += 1;
        }
        let existing = held.get(at).filter(|t| t.key() == key);
        let flags = r.u8()?;
        match parse(r, key, flags, existing)? {
            Change::New(item) => section.news.push(item),
            Change::Removed => section.removed.push(key),
        }
    }
    Ok(section)
}

/// Applies a section [`read`] checked to `held`: in place when it only changes items,
/// else in one merge. Every item held that no record names gets `rest`.
pub(super) fn fold<T: Keyed, P>(
    held: &mut Vec<T>,
    section: Section<T, P>,
    mut patch: impl FnMut(&mut T, P),
    mut rest: impl FnMut(&mut T),
) {
    let Section {
        news,
        patches,
        removed,
    } = section;
    let mut patches = patches.into_iter().peekable();
    if news.is_empty() && removed.is_empty() {
        for item in held.iter_mut() {
            let key = item.key();
            while patches.next_if(|&(k, _)| k < key).is_some() {}
            match patches.next_if(|&(k, _)| k == key) {
                Some((_, p)) => patch(item, p),
                None => rest(item),
            }
        }
        return;
    }
    let mut out = Vec::with_capacity(held.len() + news.len());
    let mut news = news.into_iter().peekable();
    let mut removed = removed.into_iter().peekable();
    for mut item in std::mem::take(held) {
        let key = item.key();
        while let Some(new) = news.next_if(|n| n.key() < key) {
            out.push(new);
        }
        while removed.next_if(|&k| k < key).is_some() {}
        if removed.next_if(|&k| k == key).is_some() {
            continue;
        }
        // Sent whole again: the new one replaces it.
        if let Some(new) = news.next_if(|n| n.key() == key) {
            out.push(new);
            continue;
        }
        while patches.next_if(|&(k, _)| k < key).is_some() {}
        match patches.next_if(|&(k, _)| k == key) {
            Some((_, p)) => patch(&mut item, p),
            None => rest(&mut item),
        }
        out.push(item);
    }
    out.extend(news);
    *held = out;
}

/// Reads a section against `held` (by increasing key) and writes what the receiver holds
/// after it to `out` (emptied first), in one pass: items without a record get `rest`; for
/// each record `apply` gets the reader at its payload, the key, the flags and a copy of
/// the held item of that key if any, and returns the item as it is now, or `None` when
/// the record removed it. `held` is left as it was, so a payload refused anywhere costs
/// nothing, and `out` is the list the frame before last was read into, so no frame
/// allocates. For items of plain data (particles) this is faster than [`read`] and
/// [`fold`] (docs/bench/engine-notes.md, "Reading particles in place"); for items that
/// own strings (bodies) each copy would allocate.
pub(super) fn read_into_copy<T: Keyed + Copy>(
    r: &mut Reader,
    held: &[T],
    out: &mut Vec<T>,
    mut apply: impl FnMut(&mut Reader, u32, u8, Option<T>) -> Result<Option<T>, DecodeError>,
    mut rest: impl FnMut(&mut T),
) -> Result<(), DecodeError> {
    // A record is at least a key gap and a flags byte.
    let n = r.count(2)?;
    out.clear();
    out.reserve(held.len().saturating_add(n));
    let mut at = 0;
    let mut key = 0u32;
    for k in 0..n {
        let gap = u32::try_from(r.varint()?)
            .map_err(|_| DecodeError::Malformed("key gap over 32 bits".into()))?;
        if gap == 0 && k > 0 {
            return Err(DecodeError::Malformed(format!("key {key} twice")));
        }
        key = key
            .checked_add(gap)
            .ok_or_else(|| DecodeError::Malformed("key overflow".into()))?;
        // The items before this record's key, which no record names.
        while let Some(mut item) = held.get(at).filter(|t| t.key() < key).copied() {
            rest(&mut item);
            out.push(item);
            at += 1;
        }
        let existing = held.get(at).filter(|t| t.key() == key).copied();
        at += usize::from(existing.is_some());
        let flags = r.u8()?;
        if let Some(item) = apply(r, key, flags, existing)? {
            out.push(item);
        }
    }
    for mut item in held[at..].iter().copied() {
        rest(&mut item);
        out.push(item);
    }
    Ok(())
}

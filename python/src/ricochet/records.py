"""A particle section's records read at once with numpy.

Records have no fixed size: varints and optional fields follow each other, so where a
record starts is known only once the record before it is read. Here, the end of a record
that would start at each byte of the section is computed for every byte at once, then the
records are found by following those ends from byte 0 (one list look-up a record), and
every field is gathered at once from the records' starts."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from .errors import DecodeError
from .layout import FROZEN, NEW, POS, REMOVED, SAME_LOOK, SAME_MOTION, VEL

# Zeros after the section: every read past its end lands here (and is then refused). A
# record read from inside the section ends within 64 bytes past it.
_PAD = 128
# The longest varint a reader takes (64 bits).
_MAX_VARINT = 10

I64 = npt.NDArray[np.int64]


@dataclass
class ParticleRecords:
    """Every record of a section, by increasing id; a field a record does not carry is
    0."""

    ids: I64
    flags: npt.NDArray[np.uint8]
    # POS: the correction; NEW: the position, in PARTICLE_QUANTUM units (resync: f32 bits).
    dq: I64
    # VEL, NEW: the velocity in PARTICLE_VEL_QUANTUM units (resync: f32 bits).
    dv: I64
    frozen: npt.NDArray[np.uint8]
    # Of NEW records only, in their order:
    motion: npt.NDArray[np.float32]  # (k, 3): acceleration x, y and drag
    c0: npt.NDArray[np.uint8]  # (k, 4)
    factor: npt.NDArray[np.float32]
    c1: npt.NDArray[np.uint8]  # (k, 4)
    life0: npt.NDArray[np.float32]
    age: I64
    size: npt.NDArray[np.float32]


class Scratch:
    """Index arrays kept from one section to the next: a key frame of 100 000 particles
    needs a few arrays of one index a byte (16 MB each), and the kernel's zeroing of
    fresh pages would cost more than the reading."""

    def __init__(self) -> None:
        self._arrays: dict[str, npt.NDArray[np.intp]] = {}

    def get(self, name: str, n: int) -> npt.NDArray[np.intp]:
        a = self._arrays.get(name)
        if a is None or len(a) < n:
            a = self._arrays[name] = np.empty(max(n, 1024), np.intp)
        return a[:n]


class _Bytes:
    """A section's bytes, padded, with the end of the varint that starts at each byte."""

    def __init__(self, section: memoryview, scratch: Scratch) -> None:
        self.size = len(section)
        self.scratch = scratch
        self.b = np.zeros(self.size + _PAD, np.uint8)
        self.b[: self.size] = np.frombuffer(section, np.uint8)
        last = len(self.b)
        # after[i]: the byte after the varint that starts at byte i (the padding's zeros
        # end any varint).
        last_byte = self.b < 0x80
        before = np.cumsum(last_byte, dtype=np.intp, out=scratch.get("before", last))
        before -= last_byte
        self.after = np.take(np.flatnonzero(last_byte), before, out=scratch.get("after", last))
        self.after += 1
        np.minimum(self.after, last - 1, out=self.after)
        # after2[i]: past two varints.
        self.after2 = np.take(self.after, self.after, out=scratch.get("after2", last))

    def clip(self, at: I64) -> I64:
        return np.minimum(at, len(self.b) - 1)

    def skip(self, at: I64) -> I64:
        """Past the varint at each of `at`."""
        return self.after[self.clip(at)]

    def varints(self, at: I64) -> npt.NDArray[np.uint64]:
        end = self.skip(at)
        length = end - at
        if len(at) and int(length.max()) > _MAX_VARINT:
            raise DecodeError("varint longer than 64 bits")
        value = np.zeros(len(at), np.uint64)
        for k in range(int(length.max()) if len(at) else 0):
            part = (self.b[self.clip(at + k)] & 0x7F).astype(np.uint64) << np.uint64(7 * k)
            value |= np.where(length > k, part, np.uint64(0))
        return value

    def svarints(self, at: I64) -> I64:
        v = self.varints(at)
        return ((v >> np.uint64(1)) ^ (np.uint64(0) - (v & np.uint64(1)))).view(np.int64)

    def raw(self, at: I64, width: int) -> npt.NDArray[np.uint8]:
        """`width` bytes at each of `at`, shape (n, width)."""
        windows = np.lib.stride_tricks.sliding_window_view(self.b, width)
        return windows[self.clip(at)]

    def f32(self, at: I64) -> npt.NDArray[np.float32]:
        return self.raw(at, 4).view("<f4").reshape(-1)

    def u32(self, at: I64) -> I64:
        return self.raw(at, 4).view("<u4").reshape(-1).astype(np.int64)


def _ends(s: _Bytes, exact: bool, only_new: bool) -> npt.NDArray[np.intp]:
    """Where a record that started at each byte of the section would end (with
    `only_new`, if it were NEW). Every index stays within the padding (a record read from
    inside the section ends within 64 bytes past it), so nothing is clipped. In place, in
    the scratch arrays."""
    n = s.size
    after, after2 = s.after[:n], s.after2
    flags = s.b[after]
    p = np.add(after, 1, out=s.scratch.get("p", n))
    # A NEW record: frozen axes, position and velocity, motion, look, final colour, life,
    # age, size.
    q, t = s.scratch.get("q", n), s.scratch.get("t", n)
    np.add(p, (flags & FROZEN) != 0, out=q)
    if exact:
        q += 16
    else:
        np.take(after2, q, out=t)
        np.take(after2, t, out=q)
    skipped = ((flags & SAME_MOTION) == 0).view(np.uint8) * np.uint8(12)
    skipped += ((flags & SAME_LOOK) == 0).view(np.uint8) * np.uint8(8)
    skipped += np.uint8(8)
    q += skipped
    np.take(s.after, q, out=t)
    t += 4
    ends = t
    if only_new:
        return ends
    # An update: a position, a velocity.
    u = s.scratch.get("u", n)
    np.copyto(u, p)
    for flag in (POS, VEL):
        has = (flags & flag) != 0
        np.copyto(u, np.take(after2, u, out=q), where=has)
    np.copyto(ends, u, where=(flags & NEW) == 0)
    np.copyto(ends, p, where=(flags & REMOVED) != 0)
    return ends


def _starts(s: _Bytes, count: int, exact: bool, only_new: bool) -> list[int]:
    """Where each of `count` records starts, followed from byte 0 (empty when they do not
    fill the section exactly)."""
    starts = [0] * count
    ends = memoryview(_ends(s, exact, only_new))  # type: ignore[arg-type]
    at = 0
    try:
        for k in range(count):
            starts[k] = at
            at = ends[at]
    except IndexError:
        raise DecodeError("particle records cut short") from None
    if at > s.size:
        raise DecodeError("particle records cut short")
    if at < s.size:
        raise DecodeError(f"{s.size - at} bytes left over")
    return starts


def read(section: memoryview, count: int, exact: bool, key: bool, scratch: Scratch) -> ParticleRecords:
    """Reads `count` records filling all of `section`; `exact` in a resync key frame,
    `key` in any key frame."""
    s = _Bytes(section, scratch)
    if count > s.size // 2:
        raise DecodeError(f"{count} particle records in {s.size} bytes")
    # A key frame's records are all NEW: that alone is followed first (checked below).
    starts_list: list[int] = []
    if key and count:
        try:
            starts_list = _starts(s, count, exact, only_new=True)
            heads = s.b[s.after[np.array(starts_list, dtype=np.intp)]]
            if ((heads & (NEW | REMOVED)) != NEW).any():
                starts_list = []
        except DecodeError:
            starts_list = []
    if count and not starts_list:
        starts_list = _starts(s, count, exact, only_new=False)
    starts = np.array(starts_list, dtype=np.int64)
    gaps = s.varints(starts).astype(np.int64)
    if count > 1 and not gaps[1:].all():
        raise DecodeError("a particle id twice in a section")
    ids = np.cumsum(gaps)
    if count and ids[-1] >= 1 << 32:
        raise DecodeError("particle id over 32 bits")
    p = s.skip(starts)
    flags = s.b[s.clip(p)]
    p = p + 1
    new = ((flags & NEW) != 0) & ((flags & REMOVED) == 0)
    update = ((flags & (NEW | REMOVED)) == 0)
    dq = np.zeros((count, 2), np.int64)
    dv = np.zeros((count, 2), np.int64)
    frozen = np.zeros(count, np.uint8)
    # Updates: POS, then VEL.
    u = p[update]
    uf = flags[update]
    has = (uf & POS) != 0
    first = s.svarints(u[has])
    second = s.svarints(s.skip(u[has]))
    dq[np.flatnonzero(update)[has]] = np.stack([first, second], axis=1)
    u = np.where(has, s.skip(s.skip(u)), u)
    has = (uf & VEL) != 0
    first = s.svarints(u[has])
    second = s.svarints(s.skip(u[has]))
    dv[np.flatnonzero(update)[has]] = np.stack([first, second], axis=1)
    # NEW records.
    q = p[new]
    nf = flags[new]
    has = (nf & FROZEN) != 0
    frozen[np.flatnonzero(new)[has]] = s.b[s.clip(q[has])]
    q = q + has
    rows = np.flatnonzero(new)
    if exact:
        dq[rows] = np.stack([s.u32(q), s.u32(q + 4)], axis=1)
        dv[rows] = np.stack([s.u32(q + 8), s.u32(q + 12)], axis=1)
        q = q + 16
    else:
        for target in (dq, dv):
            first = s.svarints(q)
            q = s.skip(q)
            target[rows] = np.stack([first, s.svarints(q)], axis=1)
            q = s.skip(q)
    has = (nf & SAME_MOTION) == 0
    motion = np.stack([s.f32(q), s.f32(q + 4), s.f32(q + 8)], axis=1)
    q = q + np.where(has, 12, 0)
    motion = _carried(motion, has, ids[rows], "motion")
    has = (nf & SAME_LOOK) == 0
    c0 = _carried(s.raw(q, 4), has, ids[rows], "look")
    factor = _carried(s.f32(q + 4), has, ids[rows], "look")
    q = q + np.where(has, 8, 0)
    c1 = s.raw(q, 4)
    life0 = s.f32(q + 4)
    q = q + 8
    age = s.varints(q).astype(np.int64)
    size = s.f32(s.skip(q))
    return ParticleRecords(
        ids=ids,
        flags=flags,
        dq=dq,
        dv=dv,
        frozen=frozen,
        motion=motion,
        c0=c0,
        factor=factor,
        c1=c1,
        life0=life0,
        age=age,
        size=size,
    )


def _carried(values: npt.NDArray[Any], has: npt.NDArray[np.bool_], ids: I64, what: str) -> npt.NDArray[Any]:
    """Each NEW record's `values`, or those of the last NEW record before it that carried
    them."""
    if has.all():
        return values
    source = np.maximum.accumulate(np.where(has, np.arange(len(has)), -1))
    if len(source) and source[0] < 0:
        raise DecodeError(f"particle {ids[0]}: no {what} before")
    return values[source]

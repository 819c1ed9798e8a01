"""The frame decoder on numpy: what a receiver knows of a world, with its particles held
as columns, so a delta frame of 100 000 particles moves them all in a few array
operations. Bodies are read as the pure decoder reads them (`ricochet.pure`); the two
decoders give the same numbers (python/tests and server/tests/python_decoder.rs check
it)."""

from __future__ import annotations

import os
from dataclasses import dataclass, replace
from typing import Any, Callable, Optional

import numpy as np
import numpy.typing as npt

from . import pure, records
from .frame import Bodies, Frame, Particles
from .errors import DecodeError
from .layout import (
    COLOR_SCALE,
    FINE,
    FREEZE_X,
    FREEZE_Y,
    KIND_DELTA,
    KIND_RESYNC,
    NEW,
    PARTICLE_QUANTUM,
    PARTICLE_VEL_QUANTUM,
    POS,
    REMOVED,
    VEL,
    PROTOCOL_VERSION,
    Reader,
)


def _native() -> Optional[Callable[[bytes, bool, int], tuple[bytearray, bytearray, bytearray]]]:
    """The Rust decoder's reading of key frames (`pip install ./python/native`), when it is
    installed, reads this layout and `RICOCHET_NATIVE` is not 0; with `RICOCHET_NATIVE=1`
    it must be there."""
    wanted = os.environ.get("RICOCHET_NATIVE", "")
    if wanted == "0":
        return None
    try:
        import ricochet_native  # type: ignore[import-not-found]
    except ImportError:
        if wanted == "1":
            raise
        return None
    if ricochet_native.PROTOCOL_VERSION != PROTOCOL_VERSION:
        if wanted == "1":
            raise ImportError(
                f"ricochet_native reads frame layout {ricochet_native.PROTOCOL_VERSION}, this package {PROTOCOL_VERSION}"
            )
        return None
    read: Callable[[bytes, bool, int], tuple[bytearray, bytearray, bytearray]] = ricochet_native.key_particles
    return read


_KEY_PARTICLES = _native()


# The rows of HeldParticles.f (f32) and HeldParticles.u (u8).
POS_X, POS_Y, VEL_X, VEL_Y, ACC_X, ACC_Y, DRAG, LIFE0, LIFE, SIZE, FACTOR = range(11)
FROZEN_X, FROZEN_Y, C0, C1 = 0, 1, 2, 6


@dataclass(frozen=True)
class HeldParticles:
    """The particles a receiver holds, by increasing id, a column each: `f` holds the f32
    fields a row each (position, velocity, acceleration, drag, initial life, life and size
    at the NEW record, size factor), `u` the bytes (frozen axes, start and final colour).
    Never changed in place (new arrays each frame), so a refused payload leaves the one
    held as it was."""

    ids: npt.NDArray[np.int64]
    f: npt.NDArray[np.float32]  # (11, n)
    u: npt.NDArray[np.uint8]  # (10, n)
    at: npt.NDArray[np.int64]  # the frame of each particle's NEW record

    @staticmethod
    def empty() -> HeldParticles:
        i = np.zeros(0, np.int64)
        return HeldParticles(i, np.zeros((11, 0), np.float32), np.zeros((10, 0), np.uint8), i)

    def __len__(self) -> int:
        return len(self.ids)

    def advanced(self, dt: np.float32, steps: int) -> HeldParticles:
        """Every particle `steps` updates on, as the engine moves it: v = (v + a dt) drag;
        p += v dt in f32, on each axis not frozen."""
        f = self.f.copy()
        pos, vel = f[POS_X : POS_Y + 1], f[VEL_X : VEL_Y + 1]
        adt = f[ACC_X : ACC_Y + 1] * dt
        drag = f[DRAG]
        frozen = self.u[FROZEN_X : FROZEN_Y + 1] != 0
        if not frozen.any():
            for _ in range(steps):
                vel += adt
                vel *= drag
                pos += vel * dt
            return replace(self, f=f)
        moving = ~frozen
        for _ in range(steps):
            v = (vel + adt) * drag
            np.copyto(pos, pos + v * dt, where=moving)
            np.copyto(vel, v, where=moving)
        return replace(self, f=f)


def _merge(held: HeldParticles, gone: npt.NDArray[np.int64], new: HeldParticles) -> HeldParticles:
    """`held` without its rows `gone`, and `new` (ids not among those kept; each by
    increasing id), as one, by increasing id: one gather a column (numpy's `take` along
    the columns is several times faster than a scatter)."""
    if not len(gone) and not len(new):
        return held
    n_held = len(held)
    rows = np.arange(n_held)
    if len(gone):
        keep = np.ones(n_held, bool)
        keep[gone] = False
        rows = np.flatnonzero(keep)
    kept_ids = held.ids[rows]
    n = len(rows) + len(new)
    # Where each column of the result comes from: a row kept, or a new one after them.
    order = np.empty(n, np.intp)
    new_slots = np.searchsorted(kept_ids, new.ids) + np.arange(len(new))
    is_new = np.zeros(n, bool)
    is_new[new_slots] = True
    order[~is_new] = rows
    order[new_slots] = n_held + np.arange(len(new))
    if not len(new):
        return HeldParticles(kept_ids, np.take(held.f, rows, axis=1), np.take(held.u, rows, axis=1), held.at[rows])
    return HeldParticles(
        np.concatenate([held.ids, new.ids])[order],
        np.take(np.concatenate([held.f, new.f], axis=1), order, axis=1),
        np.take(np.concatenate([held.u, new.u], axis=1), order, axis=1),
        np.concatenate([held.at, new.at])[order],
    )


class FrameDecoder(pure.FrameDecoder):
    """What a receiver knows of a world, kept up to date frame by frame; `frame()` gives
    it as numpy arrays. Apply payloads in the order they came with `apply`."""

    particles: HeldParticles

    def __init__(self) -> None:
        super().__init__()
        self._scratch = records.Scratch()

    def _no_particles(self) -> HeldParticles:
        return HeldParticles.empty()

    def _read_particles(self, r: Reader, kind: int, frame: int, dt: float, steps: int) -> HeldParticles:
        if kind != KIND_DELTA and _KEY_PARTICLES is not None:
            return _key_particles(_KEY_PARTICLES, r, kind, frame)
        count = r.varint()
        section = r.data[r.at :]
        recs = records.read(section, count, kind == KIND_RESYNC, kind != KIND_DELTA, self._scratch)
        r.at = len(r.data)
        held = self.particles if kind == KIND_DELTA else HeldParticles.empty()
        if kind == KIND_DELTA and len(held):
            held = held.advanced(np.float32(dt), steps)
        flags = recs.flags
        removed = (flags & REMOVED) != 0
        new = ((flags & NEW) != 0) & ~removed
        update = ~new & ~removed
        loc = np.searchsorted(held.ids, recs.ids)
        found = loc < len(held)
        found[found] = held.ids[loc[found]] == recs.ids[found]
        if (update & ~found).any():
            raise DecodeError(f"update of unknown particle {recs.ids[update & ~found][0]}")
        if update.any():
            # `held` was just moved on: its f is this frame's own.
            held = _corrected(held, recs, update, loc)
        gone = loc[(removed | new) & found]
        return _merge(held, gone, _born(recs, new, frame, kind == KIND_RESYNC))

    def to_frame(self) -> Frame:
        """The frame held, as arrays (a key frame or a delta must have been applied)."""
        if self.frame is None:
            raise DecodeError("no frame applied yet")
        bodies = [b for _, b in sorted(self.bodies.items())]
        pos = np.array([b["p"] for b in bodies], np.float64).reshape(-1, 2) * FINE
        d = np.array([b["d"] for b in bodies], np.float64).reshape(-1, 2)
        dts = np.array([b["dt"] for b in bodies], np.float64)
        vel = np.divide(d * FINE, dts[:, None], out=np.zeros_like(d), where=dts[:, None] > 0)
        p = self.particles
        # Colour and size as the engine computes them from the birth record (f32).
        elapsed = (self.frame - p.at).astype(np.float32)
        life0 = p.f[LIFE0]
        age = life0 - (p.f[LIFE] - elapsed)
        f = np.divide(age, life0, out=np.zeros_like(age), where=life0 != 0)
        c0 = p.u[C0 : C0 + 4].astype(np.float32)
        color = c0 / np.float32(COLOR_SCALE) + (p.u[C1 : C1 + 4] - c0) / np.float32(COLOR_SCALE) * f
        size = p.f[SIZE] * p.f[FACTOR] ** elapsed
        return Frame(
            number=self.frame,
            time=self.time,
            dt=self.dt,
            bodies=Bodies(
                ids=[b["id"] for b in bodies],
                groups=[b["group"] for b in bodies],
                pos=pos,
                vel=vel,
                size=np.array([b["size"] for b in bodies], np.float32).reshape(-1, 2),
                circle=np.array([b["circle"] for b in bodies], bool),
                collided=np.array([b["collided"] for b in bodies], bool),
            ),
            particles=Particles(
                ids=p.ids.astype(np.uint32),
                pos=p.f[POS_X : POS_Y + 1].T,
                vel=p.f[VEL_X : VEL_Y + 1].T,
                size=size,
                color=color.T,
            ),
            statics=len(self.statics),
            emitters=np.array(
                [[e["x"], e["y"], e["remaining"]] for e in self.emitters], np.float64
            ).reshape(-1, 3),
            stats=dict(self.stats),
        )

    def view(self) -> dict[str, Any]:
        """The frame held as plain data, as the pure decoder's `view`."""
        return self.to_frame().plain()


def _key_particles(
    read: Callable[[bytes, bool, int], tuple[bytearray, bytearray, bytearray]], r: Reader, kind: int, frame: int
) -> HeldParticles:
    """A key frame's particles, read by the Rust decoder (the section runs to the
    payload's end)."""
    try:
        ids, f, u = read(bytes(r.data[r.at :]), kind == KIND_RESYNC, frame)
    except ValueError as e:
        raise DecodeError(str(e)) from None
    r.at = len(r.data)
    n = len(ids) // 8
    return HeldParticles(
        np.frombuffer(ids, "<i8"),
        np.frombuffer(f, "<f4").reshape(11, n),
        np.frombuffer(u, np.uint8).reshape(10, n),
        np.full(n, frame, np.int64),
    )


def _corrected(
    held: HeldParticles, recs: records.ParticleRecords, update: npt.NDArray[np.bool_], loc: npt.NDArray[np.int64]
) -> HeldParticles:
    """`held` with the update records applied: a position corrected, a velocity given
    (moving again on both axes), axes frozen. Its f is changed in place (a copy moved on
    for this frame), its u copied only when a record changes what is frozen."""
    f, u = held.f, held.u
    if (recs.flags[update] & (VEL | FREEZE_X | FREEZE_Y)).any():
        u = u.copy()
    flags = recs.flags
    rows = update & ((flags & POS) != 0)
    at = loc[rows]
    moved = f[POS_X : POS_Y + 1, at].astype(np.float64) + recs.dq[rows].T * PARTICLE_QUANTUM
    f[POS_X : POS_Y + 1, at] = moved.astype(np.float32)
    rows = update & ((flags & VEL) != 0)
    at = loc[rows]
    f[VEL_X : VEL_Y + 1, at] = (recs.dv[rows].T * PARTICLE_VEL_QUANTUM).astype(np.float32)
    u[FROZEN_X : FROZEN_Y + 1, at] = 0
    at = loc[update]
    u[FROZEN_X, at] |= (flags[update] & FREEZE_X) != 0
    u[FROZEN_Y, at] |= (flags[update] & FREEZE_Y) != 0
    return replace(held, f=f, u=u)


def _born(recs: records.ParticleRecords, new: npt.NDArray[np.bool_], frame: int, exact: bool) -> HeldParticles:
    """The particles of the NEW records, as of `frame`."""
    if exact:
        pos = recs.dq[new].astype(np.uint32).view(np.float32)
        vel = recs.dv[new].astype(np.uint32).view(np.float32)
    else:
        # Positions are written against the previous NEW record's (wrapping, as the codec).
        pos = (np.cumsum(recs.dq[new], axis=0) * PARTICLE_QUANTUM).astype(np.float32)
        vel = (recs.dv[new] * PARTICLE_VEL_QUANTUM).astype(np.float32)
    n = len(recs.life0)
    f = np.empty((11, n), np.float32)
    f[POS_X : POS_Y + 1] = pos.reshape(-1, 2).T
    f[VEL_X : VEL_Y + 1] = vel.reshape(-1, 2).T
    f[ACC_X : DRAG + 1] = recs.motion.T
    f[LIFE0] = recs.life0
    f[LIFE] = (recs.life0.astype(np.float64) - recs.age).astype(np.float32)
    f[SIZE] = recs.size
    f[FACTOR] = recs.factor
    u = np.empty((10, n), np.uint8)
    frozen = recs.frozen[new]
    u[FROZEN_X] = frozen & 1
    u[FROZEN_Y] = (frozen >> 1) & 1
    u[C0 : C0 + 4] = recs.c0.T
    u[C1 : C1 + 4] = recs.c1.T
    return HeldParticles(recs.ids[new], f, u, np.full(n, frame, np.int64))

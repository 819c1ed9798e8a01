"""The frame layout's constants (protocol/src/frame/mod.rs documents each) and the byte
reader both decoders share."""

from __future__ import annotations

import struct
from typing import Any

from .errors import DecodeError

PROTOCOL_VERSION = 5
MAX_STEPS_A_FRAME = 64
FINE = 2.0**-24
# The step of positions and displacements (1/1024 units), in FINE units.
POS_STEP = 1 << 14
PARTICLE_QUANTUM = 1.0 / 1024.0
PARTICLE_VEL_QUANTUM = 1.0 / 256.0
COLOR_SCALE = 31.875
KIND_DELTA, KIND_KEY, KIND_STATICS, KIND_RESYNC = 0, 1, 2, 3
NEW, POS, VEL, COLLIDED, REMOVED, SAME_SHAPE, SAME_GROUP = 0x01, 0x02, 0x04, 0x08, 0x10, 0x40, 0x80
FROZEN, SAME_MOTION, SAME_LOOK = 0x20, 0x40, 0x80  # in a NEW particle record
FREEZE_X, FREEZE_Y = 0x20, 0x40  # in a particle record that is not NEW
I64 = 1 << 64
HEADER_BYTES = 3 + 1 + 1 + 8 + 8 + 8 + 8 + 48
STATS = (
    "step_ms",
    "contacts",
    "solver_passes",
    "deepest_penetration",
    "kinetic_energy",
    "particle_contacts",
    "overruns",
    "dynamic_bodies",
    "particles",
    "emitters",
    "energy_change",
    "residual",
)
STATS_FORMAT = "<fIIffIIIIIff"

_F32 = struct.Struct("<f")


def f32(v: float) -> float:
    """v rounded to the nearest f32, as Rust's `as f32` does; one f64 operation on f32
    values rounded so is the f32 operation."""
    try:
        return float(_F32.unpack(_F32.pack(v))[0])
    except OverflowError:
        raise DecodeError(f"{v} is out of f32 range") from None


def wrap(v: int) -> int:
    """v as a signed 64-bit integer, wrapping as the Rust codec computes."""
    v &= I64 - 1
    return v - I64 if v >= 1 << 63 else v


class Reader:
    """Bytes read in order; reading past the end is a DecodeError."""

    def __init__(self, data: bytes | memoryview) -> None:
        self.data = memoryview(data)
        self.at = 0

    def take(self, n: int) -> memoryview:
        if self.at + n > len(self.data):
            raise DecodeError(f"cut short at byte {self.at}")
        chunk = self.data[self.at : self.at + n]
        self.at += n
        return chunk

    def unpack(self, fmt: str) -> tuple[Any, ...]:
        return struct.unpack(fmt, self.take(struct.calcsize(fmt)))

    def varint(self) -> int:
        value, shift = 0, 0
        while True:
            b = self.take(1)[0]
            value |= (b & 0x7F) << shift
            if not b & 0x80:
                return value
            shift += 7
            if shift > 63:
                raise DecodeError("varint longer than 64 bits")

    def svarint(self) -> int:
        v = self.varint()
        return (v >> 1) ^ -(v & 1)

    def text(self) -> str:
        try:
            return bytes(self.take(self.varint())).decode("utf-8")
        except UnicodeDecodeError:
            raise DecodeError(f"text that is not UTF-8 before byte {self.at}") from None

"""The frame decoder in plain Python: a second, independent reading of the layout
documented in protocol/src/frame/mod.rs, checked against the Rust decoder bit for bit
(server/tests/python_decoder.rs). Slow on many particles; `ricochet.decode` moves them
with numpy and is checked against this one."""

from __future__ import annotations

import struct
from typing import Any

from .errors import DecodeError
from .layout import (
    COLLIDED,
    COLOR_SCALE,
    FINE,
    FREEZE_X,
    FREEZE_Y,
    FROZEN,
    KIND_DELTA,
    KIND_RESYNC,
    KIND_STATICS,
    MAX_STEPS_A_FRAME,
    NEW,
    PARTICLE_QUANTUM,
    PARTICLE_VEL_QUANTUM,
    POS,
    POS_STEP,
    PROTOCOL_VERSION,
    REMOVED,
    SAME_GROUP,
    SAME_LOOK,
    SAME_MOTION,
    SAME_SHAPE,
    STATS,
    STATS_FORMAT,
    VEL,
    Reader,
    f32,
    wrap,
)


def advance(p: dict[str, Any], dt: float) -> dict[str, Any]:
    """A particle one update on, as the engine moves it: v = (v + a dt) drag; p += v dt in
    f32, on each axis not frozen."""
    pos, vel = list(p["pos"]), list(p["vel"])
    for i in range(2):
        if not p["frozen"][i]:
            vel[i] = f32(f32(vel[i] + f32(p["acc"][i] * dt)) * p["drag"])
            pos[i] = f32(pos[i] + f32(vel[i] * dt))
    return dict(p, pos=pos, vel=vel)


class RangeDecoder:
    """The adaptive binary range decoder of a delta's motion (protocol/src/frame/motion.rs):
    32-bit range, 11-bit probabilities moving 1/32 of the way to each bit; zeros past the
    end of its bytes."""

    def __init__(self, data: memoryview) -> None:
        self.data, self.at, self.range, self.code = data, 0, 0xFFFFFFFF, 0
        for _ in range(4):
            self.code = ((self.code << 8) | self._next()) & 0xFFFFFFFF

    def _next(self) -> int:
        b = self.data[self.at] if self.at < len(self.data) else 0
        self.at += 1
        return b

    def _normalize(self) -> None:
        while self.range < 1 << 24:
            self.range = (self.range << 8) & 0xFFFFFFFF
            self.code = ((self.code << 8) | self._next()) & 0xFFFFFFFF

    def bit(self, probs: list[int], i: int) -> int:
        p = probs[i]
        bound = (self.range >> 11) * p
        if self.code >= bound:
            self.code -= bound
            self.range -= bound
            probs[i] = p - (p >> 5)
            bit = 1
        else:
            self.range = bound
            probs[i] = p + ((2048 - p) >> 5)
            bit = 0
        self._normalize()
        return bit

    def even(self) -> int:
        self.range >>= 1
        bit = 0
        if self.code >= self.range:
            self.code -= self.range
            bit = 1
        self._normalize()
        return bit


class MotionModel:
    """The probabilities of one delta's motion, fresh for each frame; contexts as the Rust
    `Model`: axis, speed class of d (0, within 3 steps, beyond), the residual of the body
    before (0, 1, more)."""

    def __init__(self) -> None:
        self.zero = [1024] * 18  # [axis][speed][near]
        self.sign = [1024] * 6  # [axis][sign of d]
        self.klass = [1024] * 96  # [axis][speed][k, 16]
        self.low = [1024] * 96  # [axis][k, 16][3]
        self.collided = [1024] * 2
        self.before = [0, 0]

    def residuals(self, c: RangeDecoder, d: list[int]) -> list[int]:
        out = [0, 0]
        for axis in range(2):
            v = abs(d[axis])
            speed = 0 if v == 0 else (1 if v <= 3 * POS_STEP else 2)
            near = min(abs(self.before[axis]), 2)
            if c.bit(self.zero, axis * 9 + speed * 3 + near):
                sign = (d[axis] > 0) - (d[axis] < 0) + 1
                negative = c.bit(self.sign, axis * 3 + sign)
                k = 0
                while k < 62 and c.bit(self.klass, axis * 48 + speed * 16 + min(k, 15)):
                    k += 1
                m = 1
                for j in range(k - 1, -1, -1):
                    if k - j <= 2:
                        top = (m & 1) if k - j == 2 else 0
                        bit = c.bit(self.low, axis * 48 + min(k, 15) * 3 + (k - j) - 1 + top)
                    else:
                        bit = c.even()
                    m = (m << 1) | bit
                out[axis] = -m if negative else m
            self.before[axis] = out[axis]
        return out


class Header:
    """A payload's header."""

    def __init__(self, r: Reader) -> None:
        if bytes(r.take(3)) != b"RCF":
            raise DecodeError("no RCF magic")
        version, kind = r.unpack("<BB")
        if version != PROTOCOL_VERSION:
            raise DecodeError(f"frame version {version}, this reader knows {PROTOCOL_VERSION}")
        if kind > KIND_RESYNC:
            raise DecodeError(f"unknown kind {kind}")
        self.kind: int = kind
        self.frame, self.prev, self.time, self.dt = r.unpack("<QQdd")
        if self.prev > self.frame:
            raise DecodeError(f"frame {self.frame} follows frame {self.prev}")
        self.stats: dict[str, float] = dict(zip(STATS, r.unpack(STATS_FORMAT)))


class FrameDecoder:
    """What a receiver knows of a world, kept up to date frame by frame."""

    def __init__(self) -> None:
        self.bodies: dict[int, dict[str, Any]] = {}
        self.statics: dict[int, dict[str, Any]] = {}
        self.particles: Any = self._no_particles()
        self.emitters: list[dict[str, float]] = []
        self.frame: int | None = None
        self.time = 0.0
        self.dt = 0.0
        self.stats: dict[str, float] = {}
        self.synced = False
        # Key frames dropped because the next delta followed the state before them, and
        # that state until a delta confirms the key frame (as the Rust decoder).
        self.dropped_key_frames = 0
        self.before: tuple[Any, ...] | None = None

    def _no_particles(self) -> Any:
        return {}

    def _state(self) -> tuple[Any, ...]:
        return (self.bodies, self.particles, self.emitters, self.frame, self.time, self.dt, self.stats)

    def _restore(self, state: tuple[Any, ...]) -> None:
        self.bodies, self.particles, self.emitters, self.frame, self.time, self.dt, self.stats = state

    def apply(self, data: bytes) -> int:
        """Applies a frame or a snapshot and returns its kind. A key frame applies at once,
        but the state it replaced is kept until the next delta: a delta that follows that
        state instead puts it back and drops the key frame (counted in
        dropped_key_frames)."""
        if len(data) < 21 or data[4] != KIND_DELTA:
            return self._apply_one(data)
        before = self.before
        prev = struct.unpack_from("<Q", data, 13)[0]
        if before is not None and self.synced and prev != self.frame and prev == before[3]:
            key = self._state()
            self._restore(before)
            try:
                kind = self._apply_one(data)
            except DecodeError:
                self._restore(key)
                raise
            self.before = None
            self.dropped_key_frames += 1
            return kind
        kind = self._apply_one(data)
        # The key frame is confirmed by a delta that follows it.
        self.before = None
        return kind

    def _apply_one(self, data: bytes) -> int:
        r = Reader(data)
        h = Header(r)
        kind, frame = h.kind, h.frame
        if kind == KIND_DELTA and self.synced and self.frame is not None and frame <= self.frame:
            raise DecodeError(f"frame {frame} is older than the state held")
        if kind == KIND_DELTA and not (self.synced and h.prev == self.frame):
            self.synced = False
            raise DecodeError(f"a delta frame follows frame {h.prev}, this reader holds {self.frame}")
        # Steps since the frame before: what particles move by, what a displacement spans.
        steps = frame - h.prev
        if kind == KIND_DELTA and not 1 <= steps <= MAX_STEPS_A_FRAME:
            raise DecodeError(f"{steps} steps from frame {h.prev} to {frame}")
        emitters = []
        for _ in range(r.varint()):
            x, y = r.unpack("<ff")
            emitters.append({"x": x, "y": y, "remaining": r.varint()})
        bodies = self._read_bodies(r, kind, h.dt * max(steps, 1))
        particles = self._read_particles(r, kind, frame, h.dt, steps)
        if r.at != len(r.data):
            raise DecodeError(f"{len(r.data) - r.at} bytes left over")
        if kind == KIND_STATICS:
            self.statics = bodies
            return kind
        if kind != KIND_DELTA:
            self.before = self._state() if self.synced else None
        self.bodies, self.particles, self.emitters = bodies, particles, emitters
        self.frame, self.time, self.dt, self.stats, self.synced = frame, h.time, h.dt, h.stats, True
        return kind

    def _read_bodies(self, r: Reader, kind: int, frame_dt: float) -> dict[int, dict[str, Any]]:
        """The bodies after a payload's body section; the state held is not changed."""
        # Copies on write: a payload refused half-way leaves the state held untouched.
        bodies = {} if kind != KIND_DELTA else dict(self.bodies)
        named = set()  # keys a record removes or sends whole
        units = (1, 1) if kind == KIND_RESYNC else (POS_STEP, POS_STEP)
        # Ids and positions are written against the previous record of the same kind
        # (rect, circle).
        prev: dict[str, Any] = {"id": ["", ""], "group": "", "shape": None, "p": [[0, 0], [0, 0]]}
        key = 0
        for _ in range(r.varint()):
            key += r.varint()
            flags = r.take(1)[0]
            named.add(key)
            if flags & REMOVED:
                if bodies.pop(key, None) is None:
                    raise DecodeError(f"removal of unknown body {key}")
                continue
            if not flags & NEW:
                raise DecodeError(f"body {key}: a record neither NEW nor REMOVED")
            if flags & SAME_SHAPE:
                if prev["shape"] is None:
                    raise DecodeError(f"body {key}: no shape before")
                circle, size = prev["shape"]
            else:
                circle = r.take(1)[0] != 0
                (w,) = r.unpack("<f")
                size = [w, w] if circle else [w, r.unpack("<f")[0]]
            sk = int(circle)  # the shape's kind: 0 rect, 1 circle
            shared = r.varint()
            if shared > len(prev["id"][sk].encode("utf-8")):
                raise DecodeError(f"body {key}: id prefix of {shared} bytes")
            try:
                ident = prev["id"][sk].encode("utf-8")[:shared].decode("utf-8") + r.text()
            except UnicodeDecodeError:
                raise DecodeError(f"body {key}: id prefix of {shared} bytes") from None
            group = prev["group"] if flags & SAME_GROUP else r.text()
            pu = [wrap(prev["p"][sk][0] + r.svarint()), wrap(prev["p"][sk][1] + r.svarint())]
            d = [wrap(r.svarint() * units[1]), wrap(r.svarint() * units[1])] if flags & VEL else [0, 0]
            prev["id"][sk], prev["p"][sk] = ident, pu
            prev.update(group=group, shape=(circle, size))
            bodies[key] = {
                "id": ident,
                "group": group,
                "circle": circle,
                "size": size,
                "p": [wrap(v * units[0]) for v in pu],
                "d": d,
                "dt": frame_dt,
                "collided": bool(flags & COLLIDED),
            }
        if kind == KIND_DELTA:
            # The motion: every other body held moves on, p + d, and its residuals (in
            # POS_STEPs) correct both p and d.
            c = RangeDecoder(r.take(r.varint()))
            model = MotionModel()
            for key in sorted(self.bodies):
                if key in named:
                    continue
                b = self.bodies[key]
                res = model.residuals(c, b["d"])
                changed = c.bit(model.collided, int(b["collided"]))
                d = [wrap(b["d"][i] + res[i] * POS_STEP) for i in range(2)]
                p = [wrap(b["p"][i] + b["d"][i] + res[i] * POS_STEP) for i in range(2)]
                bodies[key] = dict(b, p=p, d=d, dt=frame_dt, collided=b["collided"] != bool(changed))
            if c.at < len(c.data):
                raise DecodeError(f"motion of {len(c.data)} bytes, {len(c.data) - c.at} of them unread")
        return bodies

    def _read_particles(self, r: Reader, kind: int, frame: int, dt: float, steps: int) -> Any:
        """The particles after a payload's particle section; the state held is not
        changed. Every particle moves on as the engine moves it (f32); a record corrects
        it."""
        dt32 = f32(dt)
        particles = {}
        if kind == KIND_DELTA:
            for k, p in self.particles.items():
                for _ in range(steps):
                    p = advance(p, dt32)
                particles[k] = p
        exact = kind == KIND_RESYNC
        prev: dict[str, Any] = {"q": [0, 0], "motion": None, "look": None}
        pid = 0
        for _ in range(r.varint()):
            pid += r.varint()
            flags = r.take(1)[0]
            if flags & REMOVED:
                particles.pop(pid, None)
                continue
            if flags & NEW:
                frozen = r.take(1)[0] if flags & FROZEN else 0
                if exact:
                    pos, vel = list(r.unpack("<ff")), list(r.unpack("<ff"))
                else:
                    prev["q"] = [wrap(prev["q"][0] + r.svarint()), wrap(prev["q"][1] + r.svarint())]
                    pos = [f32(q * PARTICLE_QUANTUM) for q in prev["q"]]
                    vel = [f32(r.svarint() * PARTICLE_VEL_QUANTUM) for _ in range(2)]
                if flags & SAME_MOTION:
                    if prev["motion"] is None:
                        raise DecodeError(f"particle {pid}: no motion before")
                else:
                    prev["motion"] = r.unpack("<fff")
                if flags & SAME_LOOK:
                    if prev["look"] is None:
                        raise DecodeError(f"particle {pid}: no look before")
                else:
                    prev["look"] = (list(r.take(4)), r.unpack("<f")[0])
                ax, ay, drag = prev["motion"]
                c0, factor = prev["look"]
                c1 = list(r.take(4))
                (life0,) = r.unpack("<f")
                age = r.varint()
                (size,) = r.unpack("<f")
                particles[pid] = {
                    "pos": pos,
                    "vel": vel,
                    "acc": [ax, ay],
                    "drag": drag,
                    "frozen": [bool(frozen & 1), bool(frozen & 2)],
                    "c0": c0,
                    "c1": c1,
                    "life0": life0,
                    "life": f32(life0 - age),
                    "size": size,
                    "factor": factor,
                    "at": frame,
                }
            else:
                p = particles.get(pid)
                if p is None:
                    raise DecodeError(f"update of unknown particle {pid}")
                p = particles[pid] = dict(p)
                if flags & POS:
                    p["pos"] = [f32(p["pos"][i] + r.svarint() * PARTICLE_QUANTUM) for i in range(2)]
                if flags & VEL:
                    p["vel"] = [f32(r.svarint() * PARTICLE_VEL_QUANTUM) for _ in range(2)]
                    p["frozen"] = [False, False]
                p["frozen"] = [p["frozen"][0] or bool(flags & FREEZE_X), p["frozen"][1] or bool(flags & FREEZE_Y)]
        return particles

    def particle_view(self, p: dict[str, Any]) -> dict[str, Any]:
        """A particle's position, size and colour at the frame held."""
        assert self.frame is not None
        elapsed = self.frame - p["at"]
        age = p["life0"] - (p["life"] - elapsed)
        f = age / p["life0"] if p["life0"] else 0.0
        color = [a / COLOR_SCALE + (b - a) / COLOR_SCALE * f for a, b in zip(p["c0"], p["c1"])]
        return {"x": p["pos"][0], "y": p["pos"][1], "size": p["size"] * p["factor"] ** elapsed, "color": color}

    def view(self) -> dict[str, Any]:
        """The frame held as plain data: what `ricochet_client.py watch` prints."""

        def vel(b: dict[str, Any], i: int) -> float:
            return float(b["d"][i] * FINE / b["dt"]) if b["dt"] > 0 else 0.0

        bodies = [
            {
                "id": b["id"],
                "x": b["p"][0] * FINE,
                "y": b["p"][1] * FINE,
                "vx": vel(b, 0),
                "vy": vel(b, 1),
                "collided": b["collided"],
            }
            for _, b in sorted(self.bodies.items())
        ]
        return {
            "frame": self.frame,
            "t": self.time,
            "bodies": bodies,
            "statics": len(self.statics),
            "particles": [self.particle_view(p) for _, p in sorted(self.particles.items())],
            "emitters": len(self.emitters),
            "stats": self.stats,
        }

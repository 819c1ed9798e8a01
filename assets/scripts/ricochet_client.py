#!/usr/bin/env python3
"""A Ricochet client in Python: sends commands and decodes frames.

Needs only the standard library and `eclipse-zenoh` from PyPI:

    pip install eclipse-zenoh==1.10.2
    python3 assets/scripts/ricochet_client.py send '{"do": "press", "dir": "right"}'
    python3 assets/scripts/ricochet_client.py send spawn_minion at=[100,60]
    python3 assets/scripts/ricochet_client.py watch --frames 120

`send` takes any command, as JSON or as NAME ARG=VALUE ... (values are JSON; a bare word is
a string). The commands (docs/network.md has their arguments):

  world:  press, release, fire_dye_pack, spawn_minion, spawn_dumb_minion, select, drag,
          deselect, agitate, clear, spawn_particles, start_emitter, remove, impulse,
          set_body, spawn, set
  server: pause, resume, step, reset, bodies, load, save, restore, rewind, hashes, fork,
          close

    python3 assets/scripts/ricochet_client.py send spawn template=ball at=[25,10]
    python3 assets/scripts/ricochet_client.py send save name=break
    python3 assets/scripts/ricochet_client.py send fork world=fine 'settings={"substeps":8}'

`watch` prints one JSON object per frame: frame, time, the dynamic bodies (id, x, y, vx,
vy, collided), the static body count from the snapshot, particles (x, y, size, rgba) and
the step's figures. The frame layout is documented in protocol/src/frame/mod.rs; this file
is a second, independent reader of it.
"""
import argparse
import json
import struct
import sys
import threading
import time
import uuid

PROTOCOL_VERSION = 5
MAX_STEPS_A_FRAME = 64
MAX_TOKENS = 4096  # liveliness tokens one query keeps, as the Rust client
FINE = 2.0 ** -24
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


_F32 = struct.Struct("<f")


def f32(v):
    """v rounded to the nearest f32, as Rust's `as f32` does; one f64 operation on f32
    values rounded so is the f32 operation."""
    try:
        return _F32.unpack(_F32.pack(v))[0]
    except OverflowError:
        raise DecodeError(f"{v} is out of f32 range") from None


def advance(p, dt):
    """A particle one update on, as the engine moves it: v = (v + a dt) drag; p += v dt in
    f32, on each axis not frozen."""
    pos, vel = list(p["pos"]), list(p["vel"])
    for i in range(2):
        if not p["frozen"][i]:
            vel[i] = f32(f32(vel[i] + f32(p["acc"][i] * dt)) * p["drag"])
            pos[i] = f32(pos[i] + f32(vel[i] * dt))
    return dict(p, pos=pos, vel=vel)


def wrap(v):
    """v as a signed 64-bit integer, wrapping as the Rust codec computes."""
    v &= I64 - 1
    return v - I64 if v >= 1 << 63 else v
STATS = ("step_ms", "contacts", "solver_passes", "deepest_penetration", "kinetic_energy",
         "particle_contacts", "overruns", "dynamic_bodies", "particles", "emitters",
         "energy_change", "residual")
STATS_FORMAT = "<fIIffIIIIIff"


class RangeDecoder:
    """The adaptive binary range decoder of a delta's motion (protocol/src/frame/motion.rs):
    32-bit range, 11-bit probabilities moving 1/32 of the way to each bit; zeros past the
    end of its bytes."""

    def __init__(self, data):
        self.data, self.at, self.range, self.code = data, 0, 0xFFFFFFFF, 0
        for _ in range(4):
            self.code = ((self.code << 8) | self._next()) & 0xFFFFFFFF

    def _next(self):
        b = self.data[self.at] if self.at < len(self.data) else 0
        self.at += 1
        return b

    def _normalize(self):
        while self.range < 1 << 24:
            self.range = (self.range << 8) & 0xFFFFFFFF
            self.code = ((self.code << 8) | self._next()) & 0xFFFFFFFF

    def bit(self, probs, i):
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

    def even(self):
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

    def __init__(self):
        self.zero = [1024] * 18  # [axis][speed][near]
        self.sign = [1024] * 6  # [axis][sign of d]
        self.klass = [1024] * 96  # [axis][speed][k, 16]
        self.low = [1024] * 96  # [axis][k, 16][3]
        self.collided = [1024] * 2
        self.before = [0, 0]

    def residuals(self, c, d):
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


class DecodeError(Exception):
    pass


class Reader:
    def __init__(self, data):
        self.data = memoryview(data)
        self.at = 0

    def take(self, n):
        if self.at + n > len(self.data):
            raise DecodeError(f"cut short at byte {self.at}")
        chunk = self.data[self.at:self.at + n]
        self.at += n
        return chunk

    def unpack(self, fmt):
        return struct.unpack(fmt, self.take(struct.calcsize(fmt)))

    def varint(self):
        value, shift = 0, 0
        while True:
            b = self.take(1)[0]
            value |= (b & 0x7F) << shift
            if not b & 0x80:
                return value
            shift += 7
            if shift > 63:
                raise DecodeError("varint longer than 64 bits")

    def svarint(self):
        v = self.varint()
        return (v >> 1) ^ -(v & 1)

    def text(self):
        return bytes(self.take(self.varint())).decode("utf-8")


class FrameDecoder:
    """What a receiver knows of a world, kept up to date frame by frame."""

    def __init__(self):
        self.bodies = {}      # key -> dict
        self.statics = {}     # key -> dict
        self.particles = {}   # id -> dict
        self.emitters = []
        self.frame = None
        self.time = 0.0
        self.stats = {}
        self.synced = False
        # Key frames dropped because the next delta followed the state before them, and
        # that state until a delta confirms the key frame (as the Rust decoder).
        self.dropped_key_frames = 0
        self.before = None

    def _state(self):
        return (self.bodies, self.particles, self.emitters, self.frame, self.time, self.stats)

    def _restore(self, state):
        self.bodies, self.particles, self.emitters, self.frame, self.time, self.stats = state

    def apply(self, data):
        """Applies a frame or a snapshot. A key frame applies at once, but the state it
        replaced is kept until the next delta: a delta that follows that state instead puts
        it back and drops the key frame (counted in dropped_key_frames)."""
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

    def _apply_one(self, data):
        r = Reader(data)
        if bytes(r.take(3)) != b"RCF":
            raise DecodeError("no RCF magic")
        version, kind = r.unpack("<BB")
        if version != PROTOCOL_VERSION:
            raise DecodeError(f"frame version {version}, this reader knows {PROTOCOL_VERSION}")
        if kind > KIND_RESYNC:
            raise DecodeError(f"unknown kind {kind}")
        frame, prev_frame, t, dt = r.unpack("<QQdd")
        if prev_frame > frame:
            raise DecodeError(f"frame {frame} follows frame {prev_frame}")
        stats = dict(zip(STATS, r.unpack(STATS_FORMAT)))
        if kind == KIND_DELTA and self.synced and frame <= self.frame:
            raise DecodeError(f"frame {frame} is older than the state held")
        if kind == KIND_DELTA and not (self.synced and prev_frame == self.frame):
            self.synced = False
            raise DecodeError(f"a delta frame follows frame {prev_frame}, this reader holds {self.frame}")
        # Steps since the frame before: what particles move by, what a displacement spans.
        steps = frame - prev_frame
        if kind == KIND_DELTA and not 1 <= steps <= MAX_STEPS_A_FRAME:
            raise DecodeError(f"{steps} steps from frame {prev_frame} to {frame}")
        frame_dt = dt * max(steps, 1)
        emitters = []
        for _ in range(r.varint()):
            x, y = r.unpack("<ff")
            emitters.append({"x": x, "y": y, "remaining": r.varint()})
        # Copies on write: a payload refused half-way leaves the state held untouched.
        bodies = {} if kind != KIND_DELTA else dict(self.bodies)
        named = set()  # keys a record removes or sends whole
        units = (1, 1) if kind == KIND_RESYNC else (POS_STEP, POS_STEP)
        # Ids and positions are written against the previous record of the same kind
        # (rect, circle).
        prev = {"id": ["", ""], "group": "", "shape": None, "p": [[0, 0], [0, 0]]}
        key = 0
        for _ in range(r.varint()):
            key += r.varint()
            flags = r.take(1)[0]
            named.add(key)
            if flags & REMOVED:
                if bodies.pop(key, None) is None:
                    raise DecodeError(f"removal of unknown body {key}")
                continue
            if flags & NEW:
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
                bodies[key] = {"id": ident, "group": group, "circle": circle, "size": size,
                               "p": [wrap(v * units[0]) for v in pu], "d": d, "dt": frame_dt,
                               "collided": bool(flags & COLLIDED)}
            else:
                raise DecodeError(f"body {key}: a record neither NEW nor REMOVED")
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
        # Every particle moves on as the engine moves it (f32); a record corrects it.
        dt32 = f32(dt)
        particles = {}
        if kind == KIND_DELTA:
            for k, p in self.particles.items():
                for _ in range(steps):
                    p = advance(p, dt32)
                particles[k] = p
        exact = kind == KIND_RESYNC
        prev = {"q": [0, 0], "motion": None, "look": None}
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
                particles[pid] = {"pos": pos, "vel": vel, "acc": [ax, ay], "drag": drag,
                                  "frozen": [bool(frozen & 1), bool(frozen & 2)], "c0": c0, "c1": c1,
                                  "life0": life0, "life": f32(life0 - age), "size": size, "factor": factor,
                                  "at": frame}
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
        if r.at != len(r.data):
            raise DecodeError(f"{len(r.data) - r.at} bytes left over")
        if kind == KIND_STATICS:
            self.statics = bodies
            return kind
        if kind != KIND_DELTA:
            self.before = self._state() if self.synced else None
        self.bodies, self.particles, self.emitters = bodies, particles, emitters
        self.frame, self.time, self.stats, self.synced = frame, t, stats, True
        return kind

    def particle_view(self, p):
        elapsed = self.frame - p["at"]
        age = p["life0"] - (p["life"] - elapsed)
        f = age / p["life0"] if p["life0"] else 0.0
        color = [a / COLOR_SCALE + (b - a) / COLOR_SCALE * f for a, b in zip(p["c0"], p["c1"])]
        return {"x": p["pos"][0], "y": p["pos"][1],
                "size": p["size"] * p["factor"] ** elapsed, "color": color}

    def view(self):
        def vel(b, i):
            return b["d"][i] * FINE / b["dt"] if b["dt"] > 0 else 0.0
        bodies = [{"id": b["id"], "x": b["p"][0] * FINE, "y": b["p"][1] * FINE,
                   "vx": vel(b, 0), "vy": vel(b, 1), "collided": b["collided"]}
                  for _, b in sorted(self.bodies.items())]
        return {"frame": self.frame, "t": self.time, "bodies": bodies, "statics": len(self.statics),
                "particles": [self.particle_view(p) for _, p in sorted(self.particles.items())],
                "emitters": len(self.emitters), "stats": self.stats}


def open_session(args):
    """A zenoh session: from --config FILE (json5, as the Rust binaries read it) with the
    flags given merged over it, or else peer mode to the default endpoint."""
    import zenoh
    if args.config:
        conf = zenoh.Config.from_file(args.config)
        if args.mode:
            conf.insert_json5("mode", json.dumps(args.mode))
        if args.connect:
            conf.insert_json5("connect/endpoints", json.dumps(args.connect))
    else:
        conf = zenoh.Config()
        conf.insert_json5("mode", json.dumps(args.mode or "peer"))
        conf.insert_json5("connect/endpoints", json.dumps(args.connect or ["tcp/127.0.0.1:7447"]))
        conf.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(conf)


def parse_command(words):
    """JSON, or NAME ARG=VALUE ... with JSON values (a bare word is a string)."""
    text = " ".join(words)
    if text.lstrip().startswith("{"):
        return json.loads(text)
    command = {"do": words[0]}
    for arg in words[1:]:
        name, _, value = arg.partition("=")
        try:
            command[name] = json.loads(value)
        except ValueError:
            command[name] = value
    return command


def servers(session, world, timeout):
    """The zenoh ids holding the world's liveliness token `ricochet/<world>/alive/<zid>`.

    A callback, not a channel: zenoh hands the tokens it already knows to the query's
    handler before the query returns, so a bounded channel not yet read (the default)
    would block for good under a peer holding more tokens than it holds. At most
    MAX_TOKENS are kept: a peer may declare any number of them."""
    import zenoh
    zids, done = set(), threading.Event()

    def take(reply):
        if reply.ok is not None and len(zids) < MAX_TOKENS:
            zids.add(str(reply.ok.key_expr).rsplit("/", 1)[-1])

    session.liveliness().get(f"ricochet/{world}/alive/*",
                             handler=zenoh.handlers.Callback(take, done.set), timeout=timeout)
    # Bounded: the query ends by its timeout at the latest.
    done.wait(timeout + 0.5)
    return sorted(zids)


class Sender:
    """Names this client as the sender of its requests, as the Rust client does: zenoh's
    source info carries the id of a publisher this session declares (on the world's
    command key) and a sequence number. The server keeps a rate bucket and the remembered
    answers per sender; requests without one share the anonymous sender's."""

    def __init__(self, session, world):
        self.publisher = session.declare_publisher(f"ricochet/{world}/cmd")
        self.sequence = 0

    def source_info(self):
        import zenoh
        self.sequence += 1
        return zenoh.SourceInfo(self.publisher.id, self.sequence)


# Per world, the holder of its token that alone answered when several held it: the server
# (the others hold spare tokens without serving the world).
_pinned = {}


def server_replies(session, world, key, timeout, payload=None, sender=None):
    """The replies to a query on `key` from the world's server only: the peer holding the
    world's liveliness token. Replies from other peers are skipped with a warning. When
    several peers hold the token, the one that alone answers is the server (kept for later
    queries and `watch`); a world two holders answer for is refused. With a `Sender`, the
    query says who sent it."""
    import zenoh
    known = None
    among = {}
    extra = {"source_info": sender.source_info()} if sender is not None else {}
    for reply in session.get(key, payload=payload, timeout=timeout,
                             consolidation=zenoh.ConsolidationMode.NONE, **extra):
        zid = str(reply.replier_id.zid) if reply.replier_id is not None else None
        if known is None or zid not in known:
            known = servers(session, world, timeout)
        if zid is None or zid not in known:
            print(f"ignored a reply on {key} from {zid or 'an unknown peer'}, which does not "
                  f"hold the world's token", file=sys.stderr)
        elif len(known) == 1 or _pinned.get(world) == zid:
            yield reply
        elif _pinned.get(world) not in known:
            among.setdefault(zid, []).append(reply)
    if len(among) == 1:
        (zid, replies), = among.items()
        print(f"world {world!r}: {len(known)} peers hold its token, only {zid} answers: "
              f"taken as the server", file=sys.stderr)
        _pinned[world] = zid
        yield from replies
    elif len(among) > 1:
        raise RuntimeError(f"world {world!r} is claimed by {len(known)} peers holding its "
                           f"liveliness token ({', '.join(known)}): refusing their replies")


def request(session, world, command, timeout, attempts=3, sender=None):
    """Sends a command and returns the reply. A command (a dict) gets a random request id,
    so it is sent again, up to `attempts` times, while no answer comes: the server
    applies it once and answers every copy (of the same sender: give a `Sender`, or every
    client without one is the same anonymous sender to the server). Raw bytes are sent
    once, as they are."""
    if isinstance(command, (bytes, bytearray)):
        payload, attempts = bytes(command), 1
    else:
        command = dict(command)
        command.setdefault("id", uuid.uuid4().hex)
        payload = json.dumps(command).encode()
    for attempt in range(1, attempts + 1):
        began = time.monotonic()
        for reply in server_replies(session, world, f"ricochet/{world}/rpc", timeout, payload,
                                    sender):
            sample = reply.ok if reply.ok is not None else reply.err
            return json.loads(sample.payload.to_bytes())
        if attempt < attempts:
            print(f"no answer from the server of world {world!r}, sending again", file=sys.stderr)
            # A query nobody could take ends at once: back off before the next.
            time.sleep(min(0.1 * 2 ** (attempt - 1), max(0.0, timeout - (time.monotonic() - began))))
    raise TimeoutError(f"no reply from the server of world {world!r} after {attempts} attempt(s) "
                       f"of {timeout} s: is it up?")


def fetch(session, world, key, timeout):
    for reply in server_replies(session, world, key, timeout):
        if reply.ok is not None:
            return reply.ok.payload.to_bytes()
    return None


def watch(session, world, frames, seconds, timeout):
    decoder = FrameDecoder()
    sub = session.declare_subscriber(f"ricochet/{world}/frame")
    # Statics from the snapshot, the dynamic state now from the state query; the frames
    # that follow apply on top (older ones already queued are skipped).
    for key in ("snapshot", "state"):
        payload = fetch(session, world, f"ricochet/{world}/{key}", timeout)
        if payload is not None:
            decoder.apply(payload)
    # Frames are taken from the world's server only, as the Rust client does: the server
    # puts each with zenoh's source info naming its session; a frame from any other peer
    # (or without a source) is skipped, counted, and the holders read again at most once
    # a second.
    known, refreshed, ignored = servers(session, world, timeout), time.monotonic(), 0
    seen, began = 0, time.monotonic()
    while (frames is None or seen < frames) and (seconds is None or time.monotonic() - began < seconds):
        sample = sub.try_recv()
        if sample is None:
            time.sleep(0.002)
            if time.monotonic() - began > timeout and seen == 0:
                raise TimeoutError(f"no frames from world {world!r} within {timeout} s")
            continue
        source = sample.source_info
        zid = str(source.source_id.zid) if source is not None else None
        if zid is not None and zid not in known and time.monotonic() - refreshed >= 1.0:
            known, refreshed = servers(session, world, timeout), time.monotonic()
        if zid is None or zid not in known or (len(known) != 1 and _pinned.get(world) != zid):
            ignored += 1
            if ignored & (ignored - 1) == 0:
                print(f"ignored {ignored} frame(s) from peers that are not the world's server",
                      file=sys.stderr)
            continue
        dropped = decoder.dropped_key_frames
        try:
            decoder.apply(sample.payload.to_bytes())
        except DecodeError:
            continue
        if decoder.dropped_key_frames > dropped:
            print(f"dropped a key frame the stream did not follow ({decoder.dropped_key_frames} so far)",
                  file=sys.stderr)
        seen += 1
        print(json.dumps(decoder.view()), flush=True)
    sub.undeclare()


def decode_file(path):
    decoder = FrameDecoder()
    with open(path, "rb") as f:
        data = f.read()
    at = 0
    while at < len(data):
        (n,) = struct.unpack_from("<I", data, at)
        payload = data[at + 4:at + 4 + n]
        at += 4 + n
        if decoder.apply(payload) != KIND_STATICS:
            print(json.dumps(decoder.view()), flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--world", default="default")
    ap.add_argument("--connect", action="append", default=[], metavar="ENDPOINT")
    ap.add_argument("--mode", choices=["peer", "client"], help="peer (the default) or client")
    ap.add_argument("--config", metavar="FILE",
                    help="a zenoh configuration file (json5), e.g. assets/zenoh/client.json5; the flags given override it")
    ap.add_argument("--timeout", type=float, default=5.0)
    sub = ap.add_subparsers(dest="cmd", required=True)
    send = sub.add_parser("send", help="send one command and print the reply (the commands: "
                          "see the top of this help)")
    send.add_argument("command", nargs="+")
    send.add_argument("--raw", action="store_true", help="send the text as it is, even if it is not JSON")
    w = sub.add_parser("watch", help="print every frame as JSON")
    w.add_argument("--frames", type=int)
    w.add_argument("--seconds", type=float)
    d = sub.add_parser("decode", help="decode recorded payloads (each a u32 little-endian "
                       "length, then the bytes) and print each frame as `watch` does; no network")
    d.add_argument("file")
    args = ap.parse_args()
    if args.cmd == "decode":
        decode_file(args.file)
        return 0
    session = open_session(args)
    try:
        if args.cmd == "send":
            command = " ".join(args.command).encode() if args.raw else parse_command(args.command)
            reply = request(session, args.world, command, args.timeout,
                            sender=Sender(session, args.world))
            print(json.dumps(reply), flush=True)
            return 0 if reply.get("ok") else 1
        watch(session, args.world, args.frames, args.seconds, args.timeout)
        return 0
    finally:
        session.close()


if __name__ == "__main__":
    sys.exit(main())

"""`World`: one world of a running Ricochet server, its commands and its frames."""

from __future__ import annotations

import json
import struct
import sys
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from types import TracebackType
from typing import Any

from .commands import command
from .decode import FrameDecoder
from .errors import CommandRefused, ConnectionFailed, DecodeError, NoReply
from .frame import Frame
from .layout import KIND_DELTA, KIND_STATICS
from .session import Sender, Server, open_session, servers

Point = Sequence[float]


@dataclass(frozen=True)
class Reply:
    """The server's answer to a command (`docs/network.md`, "Commands")."""

    ok: bool
    frame: int
    """The frame the command took effect in."""
    ids: list[str] = field(default_factory=list)
    """Ids the command made, removed or touched."""
    error: str | None = None
    hash: str | None = None
    """`save` and `restore`: the state's hash."""
    bodies: list[dict[str, Any]] = field(default_factory=list)
    """`bodies`: each body's id, group, shape, size, pos, vel, mass and collided."""
    hashes: list[dict[str, Any]] = field(default_factory=list)
    """`hashes`: {"frame", "hash"} of each kept frame asked for."""
    raw: dict[str, Any] = field(default_factory=dict)
    """The reply as the server sent it."""

    @staticmethod
    def of(raw: dict[str, Any]) -> Reply:
        return Reply(
            ok=bool(raw.get("ok")),
            frame=int(raw.get("frame", 0)),
            ids=list(raw.get("ids", [])),
            error=raw.get("error"),
            hash=raw.get("hash"),
            bodies=list(raw.get("bodies", [])),
            hashes=list(raw.get("hashes", [])),
            raw=raw,
        )


class World:
    """A world served by a Ricochet server, reached over zenoh.

    ```python
    with ricochet.World.connect("tcp/127.0.0.1:7447", world="default") as world:
        world.send("impulse", body="ball", impulse=[40, 0])
        for frame in world.frames(120):
            print(frame.number, frame.bodies.pos.mean(axis=0))
    ```
    """

    def __init__(self, session: Any, world: str, timeout: float, attempts: int) -> None:
        self._session = session
        self.name = world
        self.timeout = timeout
        self.attempts = attempts
        self._server = Server(session, world)
        self._sender = Sender(session, world)

    @classmethod
    def connect(
        cls,
        endpoint: str | Sequence[str] | None = None,
        world: str = "default",
        *,
        mode: str | None = None,
        config: str | None = None,
        timeout: float = 5.0,
        attempts: int = 3,
    ) -> World:
        """Opens a zenoh session to `endpoint` (one or several, e.g.
        "tcp/127.0.0.1:7447", the default; peer mode unless `mode` says "client") or as
        the json5 file `config` says, and waits up to `timeout` seconds for the server of
        `world` to be seen. Raises ConnectionFailed when it is not. Requests wait
        `timeout` seconds for an answer and are sent up to `attempts` times."""
        endpoints = [endpoint] if isinstance(endpoint, str) else list(endpoint or [])
        session = open_session(endpoints, mode, config)
        began = time.monotonic()
        try:
            held = servers(session, world, timeout)
            while not held and time.monotonic() - began < timeout:
                time.sleep(0.1)
                held = servers(session, world, max(0.1, timeout - (time.monotonic() - began)))
        except BaseException:
            session.close()  # type: ignore[no-untyped-call]
            raise
        if not held:
            session.close()  # type: ignore[no-untyped-call]
            where = ", ".join(endpoints) or config or "tcp/127.0.0.1:7447"
            raise ConnectionFailed(
                f"no server of world {world!r} seen through {where} in "
                f"{time.monotonic() - began:.1f} s: is `ricochet-server run --world {world}` up there?"
            )
        return cls(session, world, timeout, attempts)

    def close(self) -> None:
        """Closes the zenoh session (the world goes on)."""
        self._session.close()

    def __enter__(self) -> World:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, value: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    # ---- commands -------------------------------------------------------------------

    def send(self, name: str, /, **args: Any) -> Reply:
        """Sends the command `name` with its arguments (`docs/network.md` lists them;
        `world.send("save", name="break")`) and returns the server's reply; raises
        CommandRefused with the server's reason when it refuses, NoReply when it does not
        answer."""
        reply = self.send_raw(command(name, **args))
        if not reply.ok:
            raise CommandRefused(name, reply.error or "no reason given", reply.raw)
        return reply

    def send_raw(self, message: dict[str, Any] | bytes) -> Reply:
        """Sends a command as a dict (`{"do": name, ...}`) or as the bytes of its JSON
        and returns the reply, refused or not."""
        raw = self._server.request(message, self.timeout, self.attempts, self._sender)
        return Reply.of(raw)

    def info(self) -> dict[str, Any]:
        """What the world's `info` key says: scene, bounds, dt, groups, templates,
        saves, streams, whether it is paused."""
        payload = self._server.fetch(f"ricochet/{self.name}/info", self.timeout, self._sender)
        if payload is None:
            raise NoReply(f"no answer on ricochet/{self.name}/info within {self.timeout} s")
        info: dict[str, Any] = json.loads(payload)
        return info

    def pause(self) -> Reply:
        return self.send("pause")

    def resume(self) -> Reply:
        return self.send("resume")

    def step(self, n: int) -> Reply:
        """Pauses and runs `n` steps; replies after them."""
        return self.send("step", n=n)

    def reset(self, paused: bool = False) -> Reply:
        return self.send("reset", paused=paused)

    def impulse(self, body: str, impulse: Point) -> Reply:
        """Adds `impulse` to a dynamic body's momentum: a strike."""
        return self.send("impulse", body=body, impulse=list(impulse))

    def set_body(self, body: str, pos: Point | None = None, vel: Point | None = None) -> Reply:
        args: dict[str, Any] = {"body": body}
        if pos is not None:
            args["pos"] = list(pos)
        if vel is not None:
            args["vel"] = list(vel)
        return self.send("set_body", **args)

    def spawn(
        self,
        template: str | None = None,
        at: Point | None = None,
        vel: Point | None = None,
        body: dict[str, Any] | None = None,
    ) -> str:
        """Adds a body, from a template of the scene (`template`, `at`, `vel`) or whole
        (`body`, a table of a scene's `[[body]]` fields), and returns its id."""
        args: dict[str, Any] = {}
        for name, value in (("template", template), ("at", at), ("vel", vel), ("body", body)):
            if value is not None:
                args[name] = list(value) if name in ("at", "vel") else value
        return self.send("spawn", **args).ids[0]

    def remove(self, body: str) -> Reply:
        return self.send("remove", body=body)

    def set(self, name: str, value: Any) -> Reply:
        """Sets a `[world]` field (gravity, dt, solver, substeps, ...)."""
        return self.send("set", name=name, value=value)

    def bodies(self, ids: Sequence[str] | None = None, within: Sequence[Point] | None = None) -> list[dict[str, Any]]:
        """The bodies of those ids, or within a box [[x0, y0], [x1, y1]], or all (at
        most 1 000)."""
        args: dict[str, Any] = {}
        if ids is not None:
            args["ids"] = list(ids)
        if within is not None:
            args["within"] = [list(p) for p in within]
        return self.send("bodies", **args).bodies

    def save(self, name: str) -> str:
        """Keeps the world's whole state under `name`; returns its hash."""
        return self.send("save", name=name).hash or ""

    def restore(self, name: str) -> Reply:
        return self.send("restore", name=name)

    def rewind(self, frame: int) -> Reply:
        return self.send("rewind", frame=frame)

    def hashes(self, start: int | None = None, end: int | None = None) -> list[dict[str, Any]]:
        """The state hash of each kept frame from `start` to `end`."""
        args = {k: v for k, v in (("from", start), ("to", end)) if v is not None}
        return self.send("hashes", **args).hashes

    def fork(self, world: str, settings: dict[str, Any] | None = None) -> Reply:
        """Starts a second world named `world` from this one, under other settings."""
        return self.send("fork", world=world, settings=settings or {})

    def load(self, path: str | None = None, text: str | None = None) -> Reply:
        args = {k: v for k, v in (("path", path), ("text", text)) if v is not None}
        return self.send("load", **args)

    # ---- frames ---------------------------------------------------------------------

    def payloads(self, seconds: float | None = None) -> Iterator[bytes]:
        """The raw payloads of the world's frames from its server, after the statics
        snapshot and a key frame of the state now; ends after `seconds` if given. Raises
        NoReply when no frame comes within `timeout` (a paused world sends none)."""
        session, name = self._session, self.name
        sub = session.declare_subscriber(f"ricochet/{name}/frame")
        try:
            for key in ("snapshot", "state"):
                payload = self._server.fetch(f"ricochet/{name}/{key}", self.timeout, self._sender)
                if payload is not None:
                    yield payload
            # Frames are taken from the world's server only: the server puts each with
            # zenoh's source info naming its session; a frame from any other peer is
            # skipped, counted, and the holders read again at most once a second.
            known, refreshed, ignored = servers(session, name, self.timeout), time.monotonic(), 0
            began = last = time.monotonic()
            while seconds is None or time.monotonic() - began < seconds:
                sample = sub.try_recv()
                if sample is None:
                    time.sleep(0.002)
                    if time.monotonic() - last > self.timeout:
                        raise NoReply(
                            f"no frame from world {name!r} in {time.monotonic() - last:.1f} s: "
                            "is it paused? (send resume)"
                        )
                    continue
                source = sample.source_info
                zid = str(source.source_id.zid) if source is not None else None
                if zid is not None and zid not in known and time.monotonic() - refreshed >= 1.0:
                    known, refreshed = servers(session, name, self.timeout), time.monotonic()
                pinned = self._server.pinned
                if zid is None or zid not in known or (len(known) != 1 and pinned != zid):
                    ignored += 1
                    if ignored & (ignored - 1) == 0:
                        print(f"ignored {ignored} frame(s) from peers that are not the world's server", file=sys.stderr)
                    continue
                last = time.monotonic()
                yield bytes(sample.payload.to_bytes())
        finally:
            sub.undeclare()

    def frames(self, count: int | None = None, seconds: float | None = None) -> Iterator[Frame]:
        """The world's frames as they come, decoded, bodies and particles as numpy
        arrays: `count` of them (all, if None), or for `seconds`. The first is the state
        now; frames the stream skipped (a slow reader) are skipped until the next key
        frame."""
        decoder = FrameDecoder()
        seen = 0
        if count is not None and count <= 0:
            return
        # Until a delta follows the state, a key frame queued before it (not newer) is
        # skipped: it would take the receiver back.
        joined = False
        for payload in self.payloads(seconds):
            number = struct.unpack_from("<Q", payload, 5)[0] if len(payload) >= 13 else 0
            if not joined and decoder.synced and decoder.frame is not None and number <= decoder.frame:
                continue
            dropped = decoder.dropped_key_frames
            try:
                kind = decoder.apply(payload)
            except DecodeError:
                continue
            if decoder.dropped_key_frames > dropped:
                print(
                    f"dropped a key frame the stream did not follow ({decoder.dropped_key_frames} so far)",
                    file=sys.stderr,
                )
            if kind == KIND_STATICS:
                continue
            joined = joined or kind == KIND_DELTA
            yield decoder.to_frame()
            seen += 1
            if count is not None and seen >= count:
                return

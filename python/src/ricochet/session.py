"""The zenoh side: a session, the world's server found by its liveliness token, requests
with retries, and the payloads of frames taken from that server only."""

from __future__ import annotations

import json
import sys
import threading
import time
import uuid
from collections.abc import Iterator, Sequence
from typing import Any

import zenoh

from . import identity as ids
from .errors import ConnectionFailed, NoReply, RicochetError

DEFAULT_ENDPOINT = "tcp/127.0.0.1:7447"
MAX_TOKENS = 4096  # liveliness tokens one query keeps, as the Rust client


def open_session(
    connect: Sequence[str] = (), mode: str | None = None, config: str | None = None
) -> zenoh.Session:
    """A zenoh session: from `config` (a json5 file, as the Rust binaries read it) with
    `mode` and `connect` merged over it, or else peer mode to `connect` (by default the
    server's default endpoint), multicast scouting off. It is opened under a new signing
    identity (its zenoh id is the identity's), so its requests prove their sender."""
    me = ids.Identity()
    try:
        if config:
            conf = zenoh.Config.from_file(config)
            if mode:
                conf.insert_json5("mode", json.dumps(mode))
            if connect:
                conf.insert_json5("connect/endpoints", json.dumps(list(connect)))
        else:
            conf = zenoh.Config()
            conf.insert_json5("mode", json.dumps(mode or "peer"))
            conf.insert_json5("connect/endpoints", json.dumps(list(connect) or [DEFAULT_ENDPOINT]))
            conf.insert_json5("scouting/multicast/enabled", "false")
        conf.insert_json5("id", json.dumps(me.zid))
        session = zenoh.open(conf)
        ids.remember(me)
        return session
    except zenoh.ZError as e:
        where = ", ".join(connect) or (config or DEFAULT_ENDPOINT)
        raise ConnectionFailed(f"cannot open a zenoh session to {where}: {e}") from None


def servers(session: zenoh.Session, world: str, timeout: float) -> list[str]:
    """The zenoh ids holding the world's liveliness token `ricochet/<world>/alive/<zid>`.

    A callback, not a channel: zenoh hands the tokens it already knows to the query's
    handler before the query returns, so a bounded channel not yet read (the default)
    would block for good under a peer holding more tokens than it holds. At most
    MAX_TOKENS are kept: a peer may declare any number of them."""
    zids: set[str] = set()
    done = threading.Event()

    def take(reply: zenoh.Reply) -> None:
        if reply.ok is not None and len(zids) < MAX_TOKENS:
            zids.add(str(reply.ok.key_expr).rsplit("/", 1)[-1])

    session.liveliness().get(
        f"ricochet/{world}/alive/*", handler=zenoh.handlers.Callback(take, done.set), timeout=timeout
    )
    # Bounded: the query ends by its timeout at the latest.
    done.wait(timeout + 0.5)
    return sorted(zids)


class Sender:
    """Names this client as the sender of its requests, as the Rust client does: zenoh's
    source info carries the id of a publisher this session declares (on the world's
    command key) and a sequence number, and the attachment signs the request when the
    session was opened by `open_session`. The server keeps a rate bucket and the
    remembered answers per sender; requests without a signature share the anonymous
    sender's."""

    def __init__(self, session: zenoh.Session, world: str) -> None:
        self.publisher = session.declare_publisher(f"ricochet/{world}/cmd")
        self.sequence = 0
        self.identity = ids.of_session(str(session.zid()))

    def extra(self, key: str, payload: bytes | None) -> dict[str, Any]:
        """What a query on `key` with `payload` carries to name this sender."""
        out: dict[str, Any] = {"source_info": self.source_info()}
        if self.identity is not None:
            out["attachment"] = self.identity.sign(key, payload or b"")
        return out

    def source_info(self) -> zenoh.SourceInfo:
        self.sequence += 1
        return zenoh.SourceInfo(self.publisher.id, self.sequence)


class Server:
    """Which peer is the server of a world: the one holding its liveliness token; when
    several hold it, the one that alone answers (kept for later queries and frames)."""

    def __init__(self, session: zenoh.Session, world: str) -> None:
        self.session = session
        self.world = world
        self.pinned: str | None = None

    def replies(
        self, key: str, timeout: float, payload: bytes | None = None, sender: Sender | None = None
    ) -> Iterator[zenoh.Reply]:
        """The replies to a query on `key` from the world's server only. Replies from
        other peers are skipped with a warning; a world two holders answer for is
        refused."""
        known: list[str] | None = None
        among: dict[str, list[zenoh.Reply]] = {}
        extra: dict[str, Any] = sender.extra(key, payload) if sender is not None else {}
        for reply in self.session.get(
            key, payload=payload, timeout=timeout, consolidation=zenoh.ConsolidationMode.NONE, **extra
        ):
            zid = str(reply.replier_id.zid) if reply.replier_id is not None else None
            if known is None or zid not in known:
                known = servers(self.session, self.world, timeout)
            if zid is None or zid not in known:
                print(
                    f"ignored a reply on {key} from {zid or 'an unknown peer'}, which does not "
                    f"hold the world's token",
                    file=sys.stderr,
                )
            elif len(known) == 1 or self.pinned == zid:
                yield reply
            elif self.pinned not in known:
                among.setdefault(zid, []).append(reply)
        if len(among) == 1:
            ((zid, replies),) = among.items()
            print(
                f"world {self.world!r}: {len(known or [])} peers hold its token, only {zid} "
                f"answers: taken as the server",
                file=sys.stderr,
            )
            self.pinned = zid
            yield from replies
        elif len(among) > 1:
            raise RicochetError(
                f"world {self.world!r} is claimed by {len(known or [])} peers holding its "
                f"liveliness token ({', '.join(known or [])}): refusing their replies"
            )

    def fetch(self, key: str, timeout: float, sender: Sender | None = None) -> bytes | None:
        """The payload of the server's reply on `key`, or None."""
        for reply in self.replies(key, timeout, sender=sender):
            if reply.ok is not None:
                return bytes(reply.ok.payload.to_bytes())
        return None

    def request(
        self,
        command: dict[str, Any] | bytes,
        timeout: float,
        attempts: int = 3,
        sender: Sender | None = None,
    ) -> dict[str, Any]:
        """Sends a command on the world's `rpc` key and returns the reply. A command (a
        dict) gets a random request id, so it is sent again, up to `attempts` times, while
        no answer comes: the server applies it once and answers every copy (of the same
        sender). Raw bytes are sent once, as they are."""
        if isinstance(command, (bytes, bytearray)):
            payload, attempts = bytes(command), 1
        else:
            command = dict(command)
            command.setdefault("id", uuid.uuid4().hex)
            payload = json.dumps(command).encode()
        began = time.monotonic()
        key = f"ricochet/{self.world}/rpc"
        for attempt in range(1, attempts + 1):
            sent = time.monotonic()
            for reply in self.replies(key, timeout, payload, sender):
                sample = reply.ok if reply.ok is not None else reply.err
                if sample is None:
                    continue
                answer: dict[str, Any] = json.loads(bytes(sample.payload.to_bytes()))
                return answer
            if attempt < attempts:
                print(f"no answer from the server of world {self.world!r}, sending again", file=sys.stderr)
                # A query nobody could take ends at once: back off before the next.
                time.sleep(min(0.1 * 2 ** (attempt - 1), max(0.0, timeout - (time.monotonic() - sent))))
        waited = time.monotonic() - began
        raise NoReply(
            f"no reply from the server of world {self.world!r} to {attempts} attempt(s) in "
            f"{waited:.1f} s (each waiting at most {timeout} s): is it up, and is the world's name right?"
        )

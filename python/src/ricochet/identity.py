"""Who sent a message, proven, as the Rust client does (docs/protocol.md, "Signed sender
ids"): a session opened by `open_session` takes as its zenoh id one derived from a new
Ed25519 key, and each request it sends carries, as zenoh's attachment, the public key, a
counter and a signature over the key expression, the counter and the payload. The server
gives a sender its own rate and turns only when the signature holds; other requests share
the anonymous sender's."""

from __future__ import annotations

import hashlib
import threading

from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey
from cryptography.hazmat.primitives.serialization import Encoding, PublicFormat

VERSION = 1
DOMAIN = b"ricochet sender v1\0"


def zid_of(public: bytes) -> str:
    """The zenoh id a public key names: the first 16 bytes of SHA-256 over DOMAIN and the
    key, big-endian, top bit set, in 32 lowercase hex digits."""
    first = hashlib.sha256(DOMAIN + public).digest()[:16]
    return "%032x" % (int.from_bytes(first, "big") | 1 << 127)


class Identity:
    """A key pair, the zenoh id it names, and the counter of the next message."""

    def __init__(self) -> None:
        self._key = Ed25519PrivateKey.generate()
        self.public = self._key.public_key().public_bytes(Encoding.Raw, PublicFormat.Raw)
        self.zid = zid_of(self.public)
        self._next = 0
        self._lock = threading.Lock()

    def sign(self, key: str, payload: bytes) -> bytes:
        """The attachment for the next message: version, public key, counter (u64
        little-endian), signature."""
        with self._lock:
            counter, self._next = self._next, self._next + 1
        count = counter.to_bytes(8, "little")
        signature = self._key.sign(DOMAIN + key.encode() + b"\0" + count + payload)
        return bytes([VERSION]) + self.public + count + signature


# The identity of each session `open_session` opened, by its zenoh id.
_IDENTITIES: dict[str, Identity] = {}


def remember(identity: Identity) -> None:
    _IDENTITIES[identity.zid] = identity


def of_session(zid: str) -> Identity | None:
    """The identity a session was opened under, if `open_session` opened it."""
    return _IDENTITIES.get(zid)

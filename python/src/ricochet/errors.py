"""What can go wrong, as exceptions: every one a `RicochetError`, each saying what was
wrong in its message."""

from __future__ import annotations

from typing import Any


class RicochetError(Exception):
    """Anything this package refuses or cannot do."""


class DecodeError(RicochetError):
    """A payload that is not a frame this reader can apply: malformed, of another
    version, or a delta that does not follow the state held. The state is unchanged."""


class ConnectionFailed(RicochetError):
    """No zenoh session could be opened, or no server of the world answered."""


class NoReply(RicochetError, TimeoutError):
    """The world's server did not answer a request (or sent no frame) in time."""


class CommandRefused(RicochetError):
    """The server refused a command; `reason` is its error, `reply` the whole reply."""

    def __init__(self, command: str, reason: str, reply: dict[str, Any]) -> None:
        super().__init__(f"{command} refused: {reason}")
        self.command = command
        self.reason = reason
        self.reply = reply

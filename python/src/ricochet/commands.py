"""The commands a world takes (`protocol/src/command.rs`; `docs/network.md`, "Commands"),
and the command line's short form of them."""

from __future__ import annotations

import json
from collections.abc import Sequence
from typing import Any

from .errors import RicochetError

# What the world does (`Action`), then what the server does (`ServerCommand`).
WORLD_COMMANDS = (
    "press",
    "release",
    "fire_dye_pack",
    "spawn_minion",
    "spawn_dumb_minion",
    "select",
    "drag",
    "deselect",
    "agitate",
    "clear",
    "spawn_particles",
    "start_emitter",
    "remove",
    "impulse",
    "set_body",
    "spawn",
    "set",
)
SERVER_COMMANDS = (
    "pause",
    "resume",
    "step",
    "reset",
    "bodies",
    "load",
    "save",
    "restore",
    "rewind",
    "hashes",
    "fork",
    "close",
)
COMMANDS = WORLD_COMMANDS + SERVER_COMMANDS


def command(name: str, /, **args: Any) -> dict[str, Any]:
    """The command `name` with its arguments, as the server reads it. An unknown name is
    refused here, with the names there are."""
    if name not in COMMANDS:
        raise RicochetError(f"unknown command {name!r}; the commands: {', '.join(COMMANDS)}")
    return {"do": name, **args}


def parse(words: Sequence[str]) -> dict[str, Any]:
    """JSON, or NAME ARG=VALUE ... with JSON values (a bare word is a string)."""
    text = " ".join(words)
    if text.lstrip().startswith("{"):
        try:
            parsed: dict[str, Any] = json.loads(text)
        except ValueError as e:
            raise RicochetError(f"the command is not JSON: {e}") from None
        return parsed
    message: dict[str, Any] = {"do": words[0]}
    for arg in words[1:]:
        name, _, value = arg.partition("=")
        try:
            message[name] = json.loads(value)
        except ValueError:
            message[name] = value
    return message

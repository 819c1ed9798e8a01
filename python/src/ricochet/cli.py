"""A Ricochet client in Python: sends commands and decodes frames.

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
the step's figures. `decode FILE` does the same for payloads recorded by `ricochet-server
simulate --frames FILE`, with the plain-Python decoder (the frame layout's second reading,
protocol/src/frame/mod.rs) or, with --numpy, the package's numpy decoder.

The same, as a library: `import ricochet` (python/, docs/python.md).
"""

from __future__ import annotations

import argparse
import json
import struct
import sys
from collections.abc import Iterator

from . import pure
from .commands import parse
from .decode import FrameDecoder
from .errors import RicochetError
from .layout import KIND_STATICS
from .world import World


def recorded(path: str) -> Iterator[bytes]:
    """The payloads of a file of them, each a u32 little-endian length then the bytes."""
    with open(path, "rb") as f:
        data = f.read()
    at = 0
    while at < len(data):
        if at + 4 > len(data):
            raise RicochetError(f"{path}: a length cut short at byte {at}")
        (n,) = struct.unpack_from("<I", data, at)
        if at + 4 + n > len(data):
            raise RicochetError(f"{path}: a payload of {n} bytes cut short at byte {at + 4}")
        yield data[at + 4 : at + 4 + n]
        at += 4 + n


def decode_file(path: str, numpy: bool) -> None:
    decoder = FrameDecoder() if numpy else pure.FrameDecoder()
    for payload in recorded(path):
        if decoder.apply(payload) != KIND_STATICS:
            print(json.dumps(decoder.view()), flush=True)


def arguments() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--world", default="default")
    ap.add_argument("--connect", "-e", action="append", default=[], metavar="ENDPOINT")
    ap.add_argument("--mode", "-m", choices=["peer", "client"], help="peer (the default) or client")
    ap.add_argument(
        "--config",
        "-c",
        metavar="FILE",
        help="a zenoh configuration file (json5), e.g. assets/zenoh/client.json5; the flags given override it",
    )
    ap.add_argument("--timeout", type=float, default=5.0, help="seconds to wait for an answer (default 5)")
    sub = ap.add_subparsers(dest="cmd", required=True)
    send = sub.add_parser("send", help="send one command and print the reply (the commands: see the top of this help)")
    send.add_argument("command", nargs="+")
    send.add_argument("--raw", action="store_true", help="send the text as it is, even if it is not JSON")
    w = sub.add_parser("watch", help="print every frame as JSON")
    w.add_argument("--frames", type=int)
    w.add_argument("--seconds", type=float)
    d = sub.add_parser(
        "decode",
        help="decode recorded payloads (each a u32 little-endian length, then the bytes) and print "
        "each frame as `watch` does; no network",
    )
    d.add_argument("file")
    d.add_argument("--numpy", action="store_true", help="with the numpy decoder (else the plain-Python one)")
    return ap


def main(argv: list[str] | None = None) -> int:
    args = arguments().parse_args(argv)
    try:
        return run(args)
    except RicochetError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


def run(args: argparse.Namespace) -> int:
    if args.cmd == "decode":
        decode_file(args.file, args.numpy)
        return 0
    with World.connect(args.connect, args.world, mode=args.mode, config=args.config, timeout=args.timeout) as world:
        if args.cmd == "send":
            message = " ".join(args.command).encode() if args.raw else parse(args.command)
            reply = world.send_raw(message)
            print(json.dumps(reply.raw), flush=True)
            return 0 if reply.ok else 1
        for frame in world.frames(args.frames, args.seconds):
            print(json.dumps(frame.plain()), flush=True)
    return 0

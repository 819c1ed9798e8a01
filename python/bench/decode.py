"""How long the `ricochet` package takes to decode a frame of 100 000 particles.

    python3 python/bench/decode.py --out docs/bench/python.md

Runs `ricochet-server simulate --frames` on python/bench/fire-140k.toml (140 000 fire
particles, a key frame every 60 frames, as `run` sends them), then decodes every frame with
the numpy decoder, as `World.frames()` does (apply, then the frame as arrays), `--repeat`
times, keeping each frame's fastest time. It reports the frames that hold at least
`--particles` particles: the delta frames, and the key frames apart (each holds every
particle whole), read by numpy alone and, when `pip install ./python/native` put it in
the environment, by the Rust decoder's module. The plain-Python decoder is timed on the
first such deltas beside it.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "python" / "src"))

from ricochet import decode, pure  # noqa: E402
from ricochet.cli import recorded  # noqa: E402
from ricochet.decode import FrameDecoder  # noqa: E402
from ricochet.layout import KIND_DELTA, KIND_STATICS  # noqa: E402

# The Rust decoder's key-frame reading, when `pip install ./python/native` put it here.
NATIVE = decode._KEY_PARTICLES


def server_binary(given: str | None) -> Path:
    if given:
        return Path(given)
    target = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    return target / "release" / "ricochet-server"


def machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return (
        f"{cpu}, {os.cpu_count()} cores (load average {load:.1f} as it started: other work shares them); "
        f"Python {platform.python_version()}, numpy {np.__version__}"
    )


def commit() -> str:
    out = subprocess.run(["git", "rev-parse", "--short=10", "HEAD"], cwd=ROOT, capture_output=True, text=True)
    return out.stdout.strip() or "unknown"


def timed_numpy(payloads: list[bytes], repeat: int, native: bool) -> tuple[list[float], list[int], list[int]]:
    """Each payload's fastest decoding time (ms) over `repeat` runs, its kind and the
    particles held after it; key frames read by the Rust decoder (`ricochet_native`) when
    `native`, else by numpy alone."""
    decode._KEY_PARTICLES = NATIVE if native else None
    best = [float("inf")] * len(payloads)
    kinds, held = [0] * len(payloads), [0] * len(payloads)
    for _ in range(repeat):
        decoder = FrameDecoder()
        for i, payload in enumerate(payloads):
            began = time.perf_counter()
            kinds[i] = decoder.apply(payload)
            if kinds[i] != KIND_STATICS:
                frame = decoder.to_frame()
                held[i] = len(frame.particles)
            best[i] = min(best[i], (time.perf_counter() - began) * 1e3)
    return best, kinds, held


def timed_pure(payloads: list[bytes], frames: int, particles: int) -> tuple[list[float], list[int]]:
    """The plain decoder's time (ms) on the first `frames` deltas holding `particles`,
    and the particles each held."""
    decoder = pure.FrameDecoder()
    times, held = [], []
    for payload in payloads:
        began = time.perf_counter()
        kind = decoder.apply(payload)
        if kind != KIND_STATICS:
            decoder.view()
        took = (time.perf_counter() - began) * 1e3
        if kind == KIND_DELTA and len(decoder.particles) >= particles:
            times.append(took)
            held.append(len(decoder.particles))
            if len(times) == frames:
                break
    return times, held


def row(what: str, times: list[float], held: list[int]) -> str:
    if not times:
        return f"| {what} | 0 | | | | | |"
    return (
        f"| {what} | {len(times)} | {min(held)}-{max(held)} | {statistics.median(times):.2f} | "
        f"{statistics.fmean(times):.2f} | {max(times):.2f} | {1000 / statistics.fmean(times):.3g} |"
    )


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--server", help="ricochet-server (default: $CARGO_TARGET_DIR or target/, release)")
    ap.add_argument("--scene", default=str(ROOT / "python/bench/fire-140k.toml"))
    ap.add_argument("--steps", type=int, default=120)
    ap.add_argument("--particles", type=int, default=100_000, help="frames holding at least this many count")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--pure-frames", type=int, default=3, help="deltas the plain decoder is timed on")
    ap.add_argument("--out", help="write the report (markdown) to this file")
    args = ap.parse_args()
    server = server_binary(args.server)
    if not server.exists():
        print(f"error: {server} is missing: `cargo build --release -j2` first, or give --server", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "frames.bin"
        subprocess.run(
            [str(server), "simulate", "--scene", args.scene, "--steps", str(args.steps), "--frames", str(path)],
            check=True,
            stderr=subprocess.DEVNULL,
        )
        payloads = list(recorded(str(path)))
    if NATIVE is None:
        print("note: ricochet_native is not installed (pip install ./python/native): key frames by numpy only", file=sys.stderr)
    best, kinds, held = timed_numpy(payloads, args.repeat, native=False)
    many = [i for i in range(len(payloads)) if held[i] >= args.particles]
    deltas = [i for i in many if kinds[i] == KIND_DELTA]
    keys = [i for i in many if kinds[i] != KIND_DELTA]
    pure_times, pure_held = timed_pure(payloads, args.pure_frames, args.particles)
    delta_ms = [best[i] for i in deltas]
    numpy_key_ms = [best[i] for i in keys]
    key_ms = numpy_key_ms
    if NATIVE is not None:
        native_best, _, _ = timed_numpy(payloads, args.repeat, native=True)
        key_ms = [native_best[i] for i in keys]
    budget = 1000 / 60
    scene = os.path.relpath(args.scene, ROOT)
    lines = [
        "# Decoding frames in Python",
        "",
        f"Measured by `python3 python/bench/decode.py{' --out ' + args.out if args.out else ''}` at "
        f"{commit()} on {machine()}: {args.steps} steps of `{scene}` encoded as `run` sends them (a key "
        f"frame every 60 frames), each frame decoded into numpy arrays (`FrameDecoder.apply`, then "
        f"`to_frame`), the fastest of {args.repeat} runs; the frames holding at least "
        f"{args.particles} particles:",
        "",
        "| decoder, frames | frames | particles held | median, ms | mean, ms | slowest, ms | frames a second |",
        "|---|---|---|---|---|---|---|",
        row("numpy, delta frames", delta_ms, [held[i] for i in deltas]),
        row("numpy, key frames", numpy_key_ms, [held[i] for i in keys]),
        row("numpy and `ricochet_native`, key frames", key_ms if NATIVE else [], [held[i] for i in keys]),
        row("plain Python, delta frames", pure_times, pure_held),
        "",
        "What this means for you:",
        f"- a delta frame of {args.particles} particles or more decodes in {statistics.median(delta_ms):.1f} ms "
        f"(median; slowest {max(delta_ms):.1f} ms): {sum(t < budget for t in delta_ms)} of {len(delta_ms)} "
        f"within a 60 Hz frame ({budget:.1f} ms);",
        (
            f"- a key frame (every 60 frames, and the state a joiner starts from) holds every particle whole: "
            f"{statistics.fmean(key_ms):.1f} ms with `pip install ./python/native` (the Rust decoder reads it), "
            f"{statistics.fmean(numpy_key_ms):.0f} ms with numpy alone;"
            if NATIVE
            else f"- a key frame holds every particle whole and takes {statistics.fmean(numpy_key_ms):.0f} ms "
            "with numpy alone (`pip install ./python/native` was not installed for this run);"
        )
        if key_ms
        else "- no key frame held that many;",
        f"- the plain-Python decoder, the layout's second reading, takes {statistics.fmean(pure_times):.0f} ms "
        "a delta of as many: it is for checking, not for crowds." if pure_times else "",
        "",
    ]
    report = "\n".join(lines)
    print(report)
    if args.out:
        Path(args.out).write_text(report)
    return 0


if __name__ == "__main__":
    sys.exit(main())

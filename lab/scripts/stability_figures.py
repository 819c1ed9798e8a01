#!/usr/bin/env python3
"""Runs the extreme scenes headless and prints, per scene, what stability means here:
any NaN, the worst drift of a body from its start over every step, the deepest
penetration over every step, and the kinetic energy after the last step.

    cargo build --release -p ricochet-server
    python3 lab/scripts/stability_figures.py [--steps 600] [--set NAME=VALUE ...]
    python3 lab/scripts/stability_figures.py --out docs/engine.md

With --out it measures the three settings docs/engine.md shows and writes each table
between that page's `<!-- stability-NAME:begin -->` and `<!-- stability-NAME:end -->`
markers, so the tables are the run's output and nothing else.

Reads the run's own files: the dump (`simulate --dump`, every body's position per step)
and the stats file (`simulate --stats`, the engine's figures per step). Standard library
only.
"""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SCENES = ["stack-20", "far-from-origin", "pyramid-10", "mass-ratio-1000", "overlap-quarter",
          "coincident", "zero-mass", "tunnelling", "tiny", "huge"]
# The size drift is measured in: the smallest moving body of each scene (1 elsewhere).
SIZES = {"tiny": 1e-3, "huge": 1e4, "mass-ratio-1000": 2.0, "coincident": 1.0, "tunnelling": 0.1}
# The settings docs/engine.md shows: marker name, overrides.
DOC_SETTINGS = [
    ("stability-default", []),
    ("stability-impulses", ["impulse_iterations=8", "substeps=2", "split_impulses=false",
                            "rest_load=false", "shock_propagation=false", "exact_sliding=false", "slop=0.001", "broad_phase=sweep"]),
    ("stability-chapter", ["solver=relaxation"]),
]


def measure(server, name, steps, overrides):
    """One scene under one setting: (nan, worst drift, deepest penetration, last energy)."""
    with tempfile.TemporaryDirectory() as tmp:
        dump, stats = os.path.join(tmp, "dump.jsonl"), os.path.join(tmp, "stats.jsonl")
        cmd = [server, "simulate", "--scene", os.path.join(ROOT, "assets", "scenes", name + ".toml"),
               "--steps", str(steps), "--dump", dump, "--stats", stats]
        for s in overrides:
            cmd += ["--set", s]
        subprocess.run(cmd, capture_output=True, text=True, check=True)
        frames = [json.loads(line) for line in open(dump)]
        figures = [json.loads(line) for line in open(stats)]
    start = {b["id"]: (b["x"], b["y"]) for b in frames[0]["bodies"]}
    nan, drift = False, 0.0
    for f in frames:
        for b in f["bodies"]:
            if not (math.isfinite(b["x"]) and math.isfinite(b["y"])):
                nan = True
                continue
            if b["id"] in start:
                x0, y0 = start[b["id"]]
                drift = max(drift, math.hypot(b["x"] - x0, b["y"] - y0))
    deepest = max((s["deepest_penetration"] for s in figures), default=0.0)
    energy = figures[-1]["kinetic_energy"] + 0.0 if figures else 0.0  # + 0.0: no "-0"
    return nan, drift, deepest, energy


def table(server, steps, overrides):
    rows = ["| scene | NaN | worst drift (units) | worst drift (body sizes) | deepest penetration | kinetic energy (last step) |",
            "|---|---|---|---|---|---|"]
    for name in SCENES:
        nan, drift, deepest, energy = measure(server, name, steps, overrides)
        size = SIZES.get(name, 1.0)
        rows.append(f"| {name} | {'yes' if nan else 'no'} | {drift:.4g} | {drift / size:.3g} | {deepest:.4g} | {energy:.4g} |")
    return "\n".join(rows) + "\n"


def splice(path, name, content):
    text = open(path).read()
    begin, end = f"<!-- {name}:begin -->", f"<!-- {name}:end -->"
    a, b = text.find(begin), text.find(end)
    if a < 0 or b < a:
        sys.exit(f"{path} has no {begin} ... {end} markers")
    open(path, "w").write(text[:a] + begin + "\n" + content + text[b:])


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=600)
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE")
    ap.add_argument("--out", metavar="PAGE", help="write the three tables of docs/engine.md into PAGE")
    ap.add_argument("--server", default=os.path.join(os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target")), "release", "ricochet-server"))
    args = ap.parse_args()
    if args.out:
        for name, overrides in DOC_SETTINGS:
            cmd = " ".join(["stability_figures.py", f"--steps {args.steps}"] + [f"--set {s}" for s in overrides])
            splice(args.out, name, f"Measured by `{cmd}`:\n\n" + table(args.server, args.steps, overrides))
        print(f"wrote {len(DOC_SETTINGS)} tables into {args.out}")
    else:
        print(table(args.server, args.steps, args.set), end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())

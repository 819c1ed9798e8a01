#!/usr/bin/env python3
"""Runs the extreme scenes headless and prints, per scene, what stability means here:
any NaN, the worst drift of a body from its start, the deepest penetration and the kinetic
energy of the last step.

    cargo build --release -p ricochet-server
    python3 assets/scripts/stability_figures.py [--steps 600] [--set NAME=VALUE ...]

Uses only the standard library and the `simulate --dump` contract.
"""
import argparse
import json
import math
import os
import re
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SCENES = ["stack-20", "far-from-origin", "pyramid-10", "mass-ratio-1000", "overlap-quarter",
          "coincident", "zero-mass", "tunnelling", "tiny", "huge"]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=600)
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE")
    ap.add_argument("--server", default=os.path.join(os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target")), "release", "ricochet-server"))
    args = ap.parse_args()
    print("| scene | NaN | worst drift (units) | worst drift (body sizes) | deepest penetration | kinetic energy |")
    print("|---|---|---|---|---|---|")
    for name in SCENES:
        with tempfile.NamedTemporaryFile(suffix=".jsonl") as dump:
            cmd = [args.server, "simulate", "--scene", os.path.join(ROOT, "assets", "scenes", name + ".toml"),
                   "--steps", str(args.steps), "--dump", dump.name]
            for s in args.set:
                cmd += ["--set", s]
            run = subprocess.run(cmd, capture_output=True, text=True, check=True)
            frames = [json.loads(line) for line in open(dump.name)]
        first, last = frames[0]["bodies"], frames[-1]["bodies"]
        nan = any(math.isnan(b[k]) for f in frames for b in f["bodies"] for k in ("x", "y"))
        drift, size = 0.0, 1.0
        for a, b in zip(first, last):
            d = math.hypot(a["x"] - b["x"], a["y"] - b["y"])
            if d > drift:
                drift = d
        sizes = {"tiny": 1e-3, "huge": 1e4, "mass-ratio-1000": 2.0, "coincident": 1.0, "tunnelling": 0.1}
        size = sizes.get(name, 1.0)
        deep = re.search(r"deepest penetration ([0-9.eE+-]+)", run.stderr).group(1)
        energy = re.search(r"kinetic energy ([0-9.eE+-]+)", run.stderr).group(1)
        print(f"| {name} | {'yes' if nan else 'no'} | {drift:.4g} | {drift / size:.3g} | {deep} | {energy} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())

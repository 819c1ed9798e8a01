#!/usr/bin/env bash
# The main job: a server on the chapter's emitters demo, the viewer serving Rerun's web
# viewer, and the demo script. Run from the repository after
# `cargo build --release -j2 --workspace`. Ctrl-C stops all three.
set -euo pipefail
cd "$(dirname "$0")/../.."
bin="${CARGO_TARGET_DIR:-target}/release"
pids=()
cleanup() { kill "${pids[@]}" 2>/dev/null || true; wait 2>/dev/null || true; }
trap cleanup EXIT
trap 'exit 130' INT TERM

"$bin/ricochet-server" run --scene assets/scenes/emitters.toml &
pids+=($!)
# Prints the address to open: http://127.0.0.1:9090/?url=...
"$bin/ricochet-viewer" --web &
pids+=($!)
sleep 3
echo "demo: playing assets/scripts/demo.ricochet (about 15 s); the world keeps running after it"
"$bin/ricochet" script assets/scripts/demo.ricochet
echo "demo: script done; Ctrl-C to stop"
wait

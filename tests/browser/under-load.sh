#!/usr/bin/env bash
# Runs the viewer tests (the browser test among them) RUNS times (default 10), each with
# two busy loops beside it on this 2-core machine, and prints one line per run.
#
#   bash tests/browser/under-load.sh [RUNS]
#
# Every loop is bounded: a busy loop stops after 600 s, a test run after 900 s.
set -u
runs=${1:-10}
cd "$(dirname "$0")/../.."
export CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-$HOME/.cache/ricochet-target}
cargo test --release --workspace -j2 --no-run >/dev/null 2>&1 || { echo "the tests do not build"; exit 1; }
passed=0
for n in $(seq 1 "$runs"); do
  hogs=()
  for _ in 1 2; do timeout 600 sh -c 'while :; do :; done' & hogs+=($!); done
  began=$(date +%s)
  log=$(mktemp)
  timeout 900 cargo test --release --workspace -j2 --test viewer >"$log" 2>&1
  rc=$?
  kill "${hogs[@]}" 2>/dev/null
  wait "${hogs[@]}" 2>/dev/null
  [ "$rc" -eq 0 ] && passed=$((passed + 1))
  echo "run $n: exit $rc after $(( $(date +%s) - began )) s ($(grep -h 'test result' "$log" | tail -1))"
  [ "$rc" -eq 0 ] && rm -f "$log" || echo "  log kept: $log"
done
echo "$passed of $runs passed under load"
[ "$passed" -eq "$runs" ]

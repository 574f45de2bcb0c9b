#!/usr/bin/env bash
# The graph front end's cost against grid FastSLAM's on the same inputs (issue 31): the
# whole process's CPU time (user + system) and peak RSS from GNU time, one worker thread
# each (--threads 1), the two filters run alternately (graph, gridfast, graph, …) so that
# the machine's load falls on both alike. Prints one line per input and the ratios.
#
#   scripts/cpu_ratio.sh [--slam BIN] [--rounds N] LOG…
#
# Defaults: BIN = target/release/slam, N = 1; gridfast with 30 particles, seed 0.
set -euo pipefail
slam=target/release/slam
rounds=1
logs=()
while [ $# -gt 0 ]; do
  case "$1" in
    --slam) slam="$2"; shift 2 ;;
    --rounds) rounds="$2"; shift 2 ;;
    *) logs+=("$1"); shift ;;
  esac
done
[ ${#logs[@]} -gt 0 ] || { echo "usage: $0 [--slam BIN] [--rounds N] LOG…" >&2; exit 2; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# measure NAME LOG ARGS…: prints "cpu_s rss_mb" of one run.
measure() {
  local log=$2; shift 2
  /usr/bin/time -f "%U %S %M" -o "$tmp/time" "$slam" run --quiet --threads 1 --dataset "$log" \
    --out "$tmp/out" --force "$@" > /dev/null 2> "$tmp/err" || { cat "$tmp/err" >&2; return 1; }
  awk '{ printf "%.2f %.1f\n", $1 + $2, $3 / 1024 }' "$tmp/time"
}
printf '| input | round | graph CPU (s) | gridfast CPU (s) | CPU ratio | graph peak (MB) | gridfast peak (MB) | RSS ratio |\n'
printf '|---|---|---|---|---|---|---|---|\n'
for log in "${logs[@]}"; do
  for r in $(seq 1 "$rounds"); do
    read -r gc gm < <(measure graph "$log" --filter graph)
    read -r fc fm < <(measure gridfast "$log" --filter gridfast --particles 30 --seed 0)
    awk -v n="$(basename "$log")" -v r="$r" -v gc="$gc" -v fc="$fc" -v gm="$gm" -v fm="$fm" \
      'BEGIN { printf "| %s | %d | %.1f | %.1f | %.2f | %.0f | %.0f | %.2f |\n", n, r, gc, fc, gc / fc, gm, fm, gm / fm }'
  done
done

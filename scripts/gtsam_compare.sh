#!/bin/sh
# slam-graph against GTSAM on a g2o pose graph (default: M3500). Makes a venv with GTSAM from
# PyPI in $GTSAM_VENV (default /tmp/gtsam-venv), builds examples/graph_optimize in release and
# runs scripts/gtsam_compare.py. Not part of the test suite; the figures go to
# docs/results/graph.md and the GTSAM chi2 to crates/slam-graph/tests/fixtures/.
#   scripts/gtsam_compare.sh [FILE.g2o] [--rounds N] [--slam target/release/slam [--slam-config C.toml]]
set -eu
here=$(cd "$(dirname "$0")/.." && pwd)
venv=${GTSAM_VENV:-/tmp/gtsam-venv}
file=${1:-$here/../shared/datasets/pose-graphs/input_M3500_g2o.g2o}
[ $# -gt 0 ] && shift
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet gtsam==4.3.0
fi
(cd "$here" && cargo build --release --quiet --example graph_optimize)
target=${CARGO_TARGET_DIR:-$here/target}
exec "$venv/bin/python" "$here/scripts/gtsam_compare.py" "$file" \
    --ours "$target/release/examples/graph_optimize" "$@"

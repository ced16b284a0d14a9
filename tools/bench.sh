#!/usr/bin/env bash
# `make bench` / `make bench-ros` (inside env.bash): every scenario of the paper's Tables 3-5 with both
# controllers and one Markdown report with plots.
#   bench.sh inprocess  - the in-process engine (anafi_lab/cli/experiment.py batch, virtual time, all
#                         cores): benchmarks/results/inprocess/{experiments.yaml,report.md,plots/}
#   bench.sh ros        - the ROS graph (anafi_lab/engine/ros_batch.py, experiment.launch per run):
#                         benchmarks/results/experiments.{md,yaml}, plots/
# Extra arguments go to the runner (e.g. make bench BENCH_ARGS="--controllers mpc --scenarios straight_3").
set -euo pipefail
mode="${1:-inprocess}"
[ $# -gt 0 ] && shift
case "$mode" in
  inprocess)
    exec python "$ANAFI_SIM_ROOT/anafi_lab/cli/experiment.py" batch \
      --out "$ANAFI_SIM_ROOT/benchmarks/results/inprocess" --runs-dir "${TMPDIR:-/tmp}/anafi_inprocess_runs" \
      ${BENCH_ARGS:-} "$@" ;;
  ros)
    exec python "$ANAFI_SIM_ROOT/anafi_lab/engine/ros_batch.py" ${BENCH_ARGS:-} "$@" ;;
  *)
    echo "usage: bench.sh inprocess|ros [runner arguments]" >&2; exit 2 ;;
esac

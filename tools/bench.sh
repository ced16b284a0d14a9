#!/usr/bin/env bash
# `make bench` (inside env.bash): every scenario of the paper's Tables 3-5 with both controllers,
# one Markdown report benchmarks/results/experiments.md with plots. Extra arguments go to the runner
# (e.g. make bench BENCH_ARGS="--controllers mpc --scenarios straight_3").
set -euo pipefail
exec python "$ANAFI_SIM_ROOT/benchmarks/run_experiments.py" ${BENCH_ARGS:-} "$@"

#!/usr/bin/env bash
# `make bench` / `make bench-ros` (inside env.bash): every scenario of the paper's Tables 3-5 with both
# controllers and one Markdown report with plots.
#   bench.sh inprocess [--update] - the in-process engine (anafi_lab/cli/experiment.py batch, virtual time, all
#                                   cores): experiments.yaml, report.md, plots/, runs/
#   bench.sh ros [--update]       - the ROS graph (anafi_lab/cli/ros_batch.py, experiment.launch per run):
#                                   experiments.{md,yaml}, plots/, runs/
# Where: a new run folder run/bench-<date>-<time>-<pid>/ (run/bench-ros-... for ros; run/latest links to the
# newest), so the committed results stay as they are. With --update (UPDATE=1 make bench) the report goes over the
# committed one instead (inprocess: benchmarks/results/inprocess/; ros: benchmarks/results/experiments.{md,yaml},
# plots/) and only the per-run files (summaries, CSVs, bags) into the new run folder.
# Extra arguments go to the runner (e.g. make bench BENCH_ARGS="--controllers mpc --scenarios straight_3").
set -euo pipefail
mode="${1:-inprocess}"
[ $# -gt 0 ] && shift
update=0
if [ "${1:-}" = "--update" ]; then update=1; shift; fi
new_run_dir() {   # a new folder run/<name>-<date>-<time>-<pid> of the checkout (anafi_sim.run_files.new_run_dir)
  python -c 'import sys; from anafi_sim import run_files; print(run_files.new_run_dir(sys.argv[1], sys.argv[2]))' \
    "$ANAFI_SIM_ROOT/run" "$1"
}
case "$mode" in
  inprocess)
    run_dir=$(new_run_dir bench)
    if [ "$update" = 1 ]; then out="$ANAFI_SIM_ROOT/benchmarks/results/inprocess"; else out="$run_dir"; fi
    echo "[bench] report in $out, runs in $run_dir/runs"
    # shellcheck disable=SC2086
    exec python "$ANAFI_SIM_ROOT/anafi_lab/cli/experiment.py" batch \
      --out "$out" --runs-dir "$run_dir/runs" ${BENCH_ARGS:-} "$@" ;;
  ros)
    run_dir=$(new_run_dir bench-ros)
    report=()
    [ "$update" = 1 ] || report=(--report "$run_dir/experiments.md")
    echo "[bench] report in ${report[1]:-$ANAFI_SIM_ROOT/benchmarks/results/experiments.md}, runs in $run_dir/runs"
    # shellcheck disable=SC2086
    exec python "$ANAFI_SIM_ROOT/anafi_lab/cli/ros_batch.py" --runs-dir "$run_dir/runs" "${report[@]}" \
      ${BENCH_ARGS:-} "$@" ;;
  *)
    echo "usage: bench.sh inprocess|ros [--update] [runner arguments]" >&2; exit 2 ;;
esac

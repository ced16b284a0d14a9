"""benchmarks/bench_fleet.py --calibrate-cap without a fleet: the sizes tried in order until one does not hold,
the cap's figures written into the cache (atomically, merged) that anafi_sim.launch_check reads back."""
import argparse
import importlib.util
import os

from anafi_sim import launch_check
from conftest import load_script


def _bench():
    load_script('benchmarks', 'fleet_report.py')        # bench_fleet imports it by name (beside it)
    return load_script('benchmarks', 'bench_fleet.py')


def _run(n, layout, holds, cpu_per_drone=9.0):
    fig = {'rtf': 1.0 if holds else 0.9, 'truth_hz': 100.0, 'mirror_hz': 100.0, 'mirror_in_hz': 100.0,
           'mirror_decimated_hz': 0.0, 'lag_p99_ms': 1.0, 'overruns': 0.0}
    return {'layout': layout, 'n': n, 'repeat': 0, 'drones': dict(('anafi%d' % i, dict(fig)) for i in range(n)),
            'roles': {'host fleet_ground_truth': [cpu_per_drone * n, 1]}, 'busy': 50.0, 'other_jobs': 5.0,
            'bench_cpu': 1.0, 'load_before': [1.0, 0, 0], 'load_after': [1.5, 0, 0], 'startup_s': 5.0, 'wall': 20.0,
            'largest_processes': [['host fleet_ground_truth', cpu_per_drone * n]]}


def _args(tmp_path, **kw):
    values = dict(fleet='circles', settle=5.0, duration=20.0, sizes=None, no_write=False,
                  cap_cache=str(tmp_path / 'ros' / 'anafi_sim' / 'fleet_cap.yaml'))
    values.update(kw)
    return argparse.Namespace(**values)


def test_calibration_stops_at_the_first_size_not_holding_and_writes_the_cap(tmp_path, monkeypatch):
    bench = _bench()
    monkeypatch.setattr(launch_check, 'available_cores', lambda: 2)
    tried = []

    def runs(n, layout):
        tried.append((layout, n))
        return _run(n, layout, holds=n < 20)
    args = _args(tmp_path)
    bench.calibrate(args, ['shared'], runs)
    assert tried == [('shared', n) for n in (4, 8, 12, 16, 20)]
    cap = launch_check.machine_cap('shared', 2, launch_check.cpu_model(), args.cap_cache)
    assert cap.measured and cap.figures.cpu_per_drone['shared'] == 0.09
    assert cap.figures.failing_per_core['shared'] == 10.0 and cap.drones == 19       # below the 20 that failed
    assert 'measured here on %s, 2 cores' % launch_check.cpu_model() in cap.why
    # a second layout later: merged with the first; the other layout's default untouched before
    assert not launch_check.machine_cap('per_drone', 2, launch_check.cpu_model(), args.cap_cache).measured
    bench.calibrate(_args(tmp_path, sizes=[2, 4]), ['per_drone'], lambda n, layout: _run(n, layout, True, 20.0))
    per_drone = launch_check.machine_cap('per_drone', 2, launch_check.cpu_model(), args.cap_cache)
    assert per_drone.measured and per_drone.drones == 10
    assert launch_check.machine_cap('shared', 2, launch_check.cpu_model(), args.cap_cache).drones == 19
    assert [f for f in os.listdir(os.path.dirname(args.cap_cache))] == ['fleet_cap.yaml']   # no temporary left


def test_nothing_held_or_no_write_leaves_the_default(tmp_path, monkeypatch):
    bench = _bench()
    args = _args(tmp_path)
    bench.calibrate(args, ['shared'], lambda n, layout: _run(n, layout, False))
    assert not os.path.exists(args.cap_cache)
    bench.calibrate(_args(tmp_path, no_write=True), ['shared'], lambda n, layout: _run(n, layout, n < 8))
    assert not os.path.exists(args.cap_cache)

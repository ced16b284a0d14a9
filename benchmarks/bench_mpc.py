#!/usr/bin/env python
"""Benchmark: MPC (anafi_control.mpc) solve and per-cycle time at N = 30, set up once vs rebuilt every cycle.

Closed loop on the MPC's own model (double integrator, dt = 0.1 s, u0 applied each cycle) with a little
seeded measurement noise, three scenarios of ``--cycles`` cycles each: a waypoint on a 3 m/s straight line,
a waypoint on a circle (r = 10 m, 3 m/s) and static waypoints jumping between (0, 0, 5) and (3, 2, 5) every
10 s (the paper's Fig. 6 target). Two controllers run side by side, one cycle each in turn, so background
load hits both alike:

* ``setup once``: OSQP set up once, per cycle update(q, l, u) and warm start (the default);
* ``rebuild``: the whole QP built and set up from scratch every cycle (as the paper's code rebuilt P);
* ``plain numerics``: setup once without the robust settings (no polish, no verification, unscaled
  cumulative errors, ``PLAIN_NUMERICS``), to show the price of the robust numerics side by side.

Times: ``solve`` = OSQP info.solve_time, ``cycle`` = wall time of CumulativeErrorMpc.solve() (vector
updates, setup if any, solve, result extraction). Prints a table and writes benchmarks/results/mpc.md.

Run (inside env.bash): python benchmarks/bench_mpc.py [--cycles 2000] [--no-write]
"""
import argparse
import math
import os
import platform
import time

import numpy as np
import osqp
import scipy

from anafi_control.mpc import CumulativeErrorMpc
from anafi_sim.processes import cpu_model

#: the MPC without its robust settings (wrong answers after waypoint jumps, see test_mpc.py)
PLAIN_NUMERICS = {'polish': False, 'verify': False, 'cum_scale': 1.0, 'accept_inaccurate': False}
NAMES = ('setup once', 'plain numerics', 'rebuild')

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

DT = 0.1
POS_NOISE = 0.02   # [m] 1-sigma measurement noise
VEL_NOISE = 0.05   # [m/s]


def waypoint(scenario, t):
    """(position, velocity) of the waypoint at time t [s], ENU."""
    if scenario == 'line 3 m/s':
        return np.array([3.0 * t, 0.0, 5.0]), np.array([3.0, 0.0, 0.0])
    if scenario == 'circle r=10 m, 3 m/s':
        w = 3.0 / 10.0
        return (np.array([10.0 * math.cos(w * t), 10.0 * math.sin(w * t), 5.0]),
                np.array([-3.0 * math.sin(w * t), 3.0 * math.cos(w * t), 0.0]))
    if scenario == 'static steps (3, 2, 5)':
        on = int(t // 10.0) % 2 == 0
        return np.array([3.0, 2.0, 5.0]) if on else np.array([0.0, 0.0, 5.0]), np.zeros(3)
    raise ValueError(scenario)


SCENARIOS = ('line 3 m/s', 'circle r=10 m, 3 m/s', 'static steps (3, 2, 5)')


class Loop(object):
    """One controller closing the loop on the double-integrator model."""

    def __init__(self, controller, scenario, seed):
        self.c = controller
        self.scenario = scenario
        self.rng = np.random.RandomState(seed)
        p0, _ = waypoint(scenario, 0.0)
        self.p = p0 if scenario != 'static steps (3, 2, 5)' else np.array([0.0, 0.0, 5.0])
        self.p = self.p.copy()
        self.v = np.zeros(3)
        self.k = 0
        self.rows = []

    def step(self):
        t = self.k * DT
        wp, wv = waypoint(self.scenario, t)
        pm = self.p + self.rng.normal(0.0, POS_NOISE, 3)
        vm = self.v + self.rng.normal(0.0, VEL_NOISE, 3)
        err = float(np.linalg.norm(wp - self.p))  # true tracking error at the solve instant
        c0 = time.process_time()
        r = self.c.solve(pm, vm, wp, wv)
        cpu = time.process_time() - c0
        a = np.array(r.u0) if r.ok else np.zeros(3)  # the model integrates a_z (eq. 7), not the v_z command
        self.p = self.p + DT * self.v + 0.5 * DT * DT * a
        self.v = self.v + DT * a
        self.k += 1
        self.rows.append((r.solve_time, r.run_time, r.setup_time, r.iterations, cpu, r.ok, err))


def stats(rows):
    arr = np.array([r[:5] for r in rows], dtype=float)
    ok = np.array([r[5] for r in rows], dtype=bool)
    err = np.array([r[6] for r in rows], dtype=float)
    ms = 1e3
    return {
        'solve_p50': np.percentile(arr[:, 0], 50) * ms, 'solve_p99': np.percentile(arr[:, 0], 99) * ms,
        'cycle_p50': np.percentile(arr[:, 1], 50) * ms, 'cycle_p99': np.percentile(arr[:, 1], 99) * ms,
        'cycle_max': arr[:, 1].max() * ms, 'cycle_mean': arr[:, 1].mean() * ms,
        'setup_p50': np.percentile(arr[:, 2], 50) * ms,
        'iter_p50': np.percentile(arr[:, 3], 50), 'iter_p99': np.percentile(arr[:, 3], 99),
        'iter_max': arr[:, 3].max(), 'cpu_p50': np.percentile(arr[:, 4], 50) * ms,
        'cpu_p99': np.percentile(arr[:, 4], 99) * ms,
        'fail': int((~ok).sum()), 'n': len(rows), 'err': err[50:].mean() if len(err) > 50 else err.mean(),
    }


HEADER = ('| controller | scenario | solve p50 [ms] | solve p99 [ms] | cycle p50 [ms] | cycle p99 [ms] | '
          'cycle max [ms] | cycle CPU p50/p99 [ms] | iterations p50/p99/max | failed | mean e [m] |')
SEP = '|' + '---|' * 11


def fmt_row(name, scenario, s):
    return ('| %s | %s | %.3f | %.3f | %.3f | %.3f | %.2f | %.3f/%.3f | %d/%d/%d | %d/%d | %.3f |' % (
        name, scenario, s['solve_p50'], s['solve_p99'], s['cycle_p50'], s['cycle_p99'], s['cycle_max'],
        s['cpu_p50'], s['cpu_p99'], s['iter_p50'], s['iter_p99'], s['iter_max'], s['fail'], s['n'], s['err']))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--cycles', type=int, default=2000, help='cycles per scenario (default 2000)')
    ap.add_argument('--no-write', action='store_true', help='do not write benchmarks/results/mpc.md')
    args = ap.parse_args()

    all_rows = dict((name, []) for name in NAMES)
    lines = [HEADER, SEP]
    for i, scenario in enumerate(SCENARIOS):
        loops = {'setup once': Loop(CumulativeErrorMpc(), scenario, seed=i),
                 'plain numerics': Loop(CumulativeErrorMpc(PLAIN_NUMERICS), scenario, seed=i),
                 'rebuild': Loop(CumulativeErrorMpc({'rebuild_every_cycle': True}), scenario, seed=i)}
        for _ in range(args.cycles):
            for name in NAMES:
                loops[name].step()
        for name, loop in loops.items():
            all_rows[name].extend(loop.rows)
            lines.append(fmt_row(name, scenario, stats(loop.rows)))
    totals = dict((name, stats(rows)) for name, rows in all_rows.items())
    for name in NAMES:
        lines.append(fmt_row('**%s**' % name, 'all', totals[name]))
    a, b = totals['setup once'], totals['rebuild']
    ratio = ('rebuild / setup once: cycle p50 x%.2f, cycle p99 x%.2f, cycle mean x%.2f, cycle CPU p50 x%.2f, '
             'cycle CPU p99 x%.2f (rebuild setup p50 %.3f ms per cycle)' % (
                 b['cycle_p50'] / a['cycle_p50'], b['cycle_p99'] / a['cycle_p99'],
                 b['cycle_mean'] / a['cycle_mean'], b['cpu_p50'] / a['cpu_p50'], b['cpu_p99'] / a['cpu_p99'],
                 b['setup_p50']))
    o = totals['plain numerics']
    ratio += ('\n- setup once (robust numerics) / plain numerics: cycle p50 x%.2f, cycle p99 x%.2f, cycle CPU p50 '
              'x%.2f, cycle CPU p99 x%.2f' % (a['cycle_p50'] / o['cycle_p50'], a['cycle_p99'] / o['cycle_p99'],
                                             a['cpu_p50'] / o['cpu_p50'], a['cpu_p99'] / o['cpu_p99']))
    target = 'target p99 < 5 ms (cycle, setup once): %s (%.3f ms)' % (
        'met' if a['cycle_p99'] < 5.0 else 'NOT met', a['cycle_p99'])
    machine = ('CPU: %s, %d logical cores; Python %s; osqp %s; numpy %s; scipy %s' % (
        cpu_model(), os.cpu_count() or 0, platform.python_version(), osqp.__version__, np.__version__,
        scipy.__version__))
    table = '\n'.join(lines)
    print(machine)
    print(table)
    print(ratio)
    print(target)

    if not args.no_write:
        out_dir = os.path.join(ROOT, 'benchmarks', 'results')
        if not os.path.isdir(out_dir):
            os.makedirs(out_dir)
        with open(os.path.join(out_dir, 'mpc.md'), 'w') as f:
            f.write('# MPC solve time (anafi_control.mpc, N = 30, dt = 0.1 s)\n\n')
            f.write('Generated by `benchmarks/bench_mpc.py --cycles %d`. %s.\n\n' % (args.cycles, machine))
            f.write('Closed loop on the MPC model (double integrator, seeded noise %.2f m / %.2f m/s), '
                    '%d cycles per scenario; both controllers run in the same process, alternating cycles. '
                    '`solve` = OSQP info.solve_time; `cycle` = wall time of one '
                    '`CumulativeErrorMpc.solve()` call (vector updates, setup if any, solve, result '
                    'extraction); `cycle CPU` = process CPU time of that call (insensitive to other load on '
                    'the shared machine, which shows in the wall-time tails). `setup once` = OSQP set up once, '
                    'per cycle update(q, l, u), warm start; '
                    '`rebuild` = whole QP built and set up from scratch every cycle (as the paper\'s code '
                    'rebuilt P), cold start. mean e = mean |waypoint - drone| after the first 5 s.\n\n'
                    % (POS_NOISE, VEL_NOISE, args.cycles))
            f.write(table + '\n\n')
            f.write('- ' + ratio + '\n- ' + target + '\n')
        print('wrote %s' % os.path.join(out_dir, 'mpc.md'))


if __name__ == '__main__':
    main()

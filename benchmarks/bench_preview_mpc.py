#!/usr/bin/env python3
"""The preview MPC (anafi_control/preview_mpc.py) against the paper's MPC and PID, in-process (engine).

    python benchmarks/bench_preview_mpc.py scenarios [--workers 2] [--out DIR]   # moving + static scenarios
    python benchmarks/bench_preview_mpc.py wind [--seeds 10] [--workers 2]        # 4 m/s wind + 1 m/s gusts
    python benchmarks/bench_preview_mpc.py airship [--workers 2]                  # follow the airship (no preview)
    python benchmarks/bench_preview_mpc.py cycle                                  # cycle time p50/p99 [ms]

Every figure comes from ``anafi_lab.engine.engine.Engine`` runs (the same cores as the ROS nodes on
virtual time, deterministic). Columns: e_mu against the ground truth and the estimate as the evaluator
computes it (the waypoint of a sample = the latest 10 Hz waypoint, zero-order hold), and e_mu_ref: the
ground truth against the scenario's continuous reference at the sample time (where the target really is;
the zero-order hold alone costs ~v x 0.05 s on average against the held waypoint). Static scenarios:
overshoot past the target along the step [m] and settling time to within 0.1 m [s] (ground truth).
Controller CPU per simulated second of the measured window [s/s] (wall-clock: varies with the load, compare
within one run). ``cycle``: wall time of every ``cycle()`` call in one run of circle_r3_v3 per controller.
Writes Markdown to stdout (and DIR/<command>.md with --out).
"""
import argparse
import concurrent.futures
import os
import sys
import time

import numpy as np

from anafi_lab.engine.engine import Engine
from anafi_lab.paper import ALL_SCENARIOS
from anafi_sim.numeric import fmt

MOVING = [s for s in ALL_SCENARIOS if not s.startswith('static')]
STATIC = [s for s in ALL_SCENARIOS if s.startswith('static')]
CIRCLES = [s for s in ALL_SCENARIOS if s.startswith('circle')]
#: label -> (controller, params)
VARIANTS = {
    'preview_mpc': ('preview_mpc', {}),
    'preview_mpc (no preview)': ('preview_mpc', {'use_preview': False}),
    'mpc': ('mpc', None),
    'pid': ('pid', None),
}
DEFAULT_LABELS = 'preview_mpc,preview_mpc (no preview),mpc,pid'
AIRSHIP_LABELS = ['preview_mpc (no preview)', 'mpc', 'pid']   # a seen target: no preview
WIND = {'wind_x': 3.2, 'wind_y': 2.4, 'gust_std_horizontal': 1.0, 'gust_std_vertical': 0.3,   # |mean| 4 m/s
        'gust_time_constant': 2.0}


def run_one(job):
    """One engine run -> dict of figures (a module-level function: picklable for the process pool)."""
    scenario, label, seed, wind = job
    controller, params = VARIANTS[label]
    eng = Engine(scenario, controller, seed=seed, wind=wind, controller_params=params)
    res = eng.run()
    out = {'scenario': scenario, 'label': label, 'seed': seed, 'ok': res.ok,
           'cpu': res.info.get('controller_cpu_per_sim_s')}
    if not res.ok or res.evaluation is None:
        return out
    s = res.summary
    out['e_mu_truth'] = s['truth']['e_mu']
    out['e_mu_est'] = s['estimate']['e_mu']
    out.update(_continuous(eng, res.evaluation))
    return out


def _continuous(eng, evaluation):
    """e_mu of the truth against the scenario's reference at the sample time, and the static step figures."""
    log = evaluation.log
    t = np.asarray(log.time, dtype=float)
    truth = np.column_stack([np.asarray(log.columns['%s_sphinx' % a], dtype=float) for a in 'xyz'])
    ref = np.array([tuple(eng.scenario.waypoint(ti - eng.started_at))[:3] for ti in t])
    err = np.linalg.norm(truth - ref, axis=1)
    out = {'e_mu_ref': float(np.nanmean(err))}
    if eng.scenario.trajectory.kind == 'static':
        full = evaluation.full_log
        ft = np.asarray(full.time, dtype=float)
        p = np.column_stack([np.asarray(full.columns['%s_sphinx' % a], dtype=float) for a in 'xyz'])
        start = np.array(eng.scenario.start[:3])
        target = np.array(eng.scenario.final[:3])
        step_t = eng.started_at + eng.scenario.measure_window[0]
        after = ft >= step_t
        d = target - start
        dist = np.linalg.norm(d)
        along = (p[after] - start).dot(d / dist) if dist > 0 else np.zeros(after.sum())
        out['overshoot'] = float(max(0.0, np.nanmax(along) - dist)) if dist > 0 else 0.0
        e = np.linalg.norm(p[after] - target, axis=1)
        outside = np.nonzero(e > 0.1)[0]
        out['settling'] = float(ft[after][outside[-1]] - step_t) if len(outside) else 0.0
    return out


def _pool(jobs, workers):
    results = []
    with concurrent.futures.ProcessPoolExecutor(workers) as ex:
        for r in ex.map(run_one, jobs):
            results.append(r)
            print('RUN %s' % dict((k, round(v, 4) if isinstance(v, float) else v) for k, v in r.items()),
                  file=sys.stderr, flush=True)
    return results


def cmd_scenarios(args):
    labels = args.labels.split(',')
    jobs = [(s, l, None, None) for s in MOVING + STATIC for l in labels]
    results = _pool(jobs, args.workers)
    by = dict(((r['scenario'], r['label']), r) for r in results)
    lines = ['## Moving scenarios: e_mu [m] (ground truth vs held waypoint / truth vs continuous reference / '
             'estimate vs held waypoint)', '',
             '| scenario | ' + ' | '.join(labels) + ' |', '|---|' + '---|' * len(labels)]
    for s in MOVING:
        cells = []
        for l in labels:
            r = by[(s, l)]
            cells.append('%s / %s / %s' % (fmt(r.get('e_mu_truth'), 3), fmt(r.get('e_mu_ref'), 3),
                                           fmt(r.get('e_mu_est'), 3)) if r['ok'] else 'FAILED')
        lines.append('| %s | %s |' % (s, ' | '.join(cells)))
    for key, what in (('e_mu_truth', 'truth vs held waypoint'), ('e_mu_ref', 'truth vs continuous reference')):
        lines.append('| **max %s** | %s |' % (what, ' | '.join(
            fmt(max(by[(s, l)].get(key, float('nan')) for s in MOVING), 3) for l in labels)))
    lines += ['', '## Static waypoints (ground truth): overshoot [m] / settling to 0.1 m [s] / e_mu [m]', '',
              '| scenario | ' + ' | '.join(labels) + ' |', '|---|' + '---|' * len(labels)]
    for s in STATIC:
        lines.append('| %s | %s |' % (s, ' | '.join('%s / %s / %s' % (
            fmt(by[(s, l)].get('overshoot'), 3), fmt(by[(s, l)].get('settling'), 2),
            fmt(by[(s, l)].get('e_mu_truth'), 3)) for l in labels)))
    lines += ['', '## Controller CPU per simulated second [s/s], mean over the moving scenarios', '',
              '| ' + ' | '.join(labels) + ' |', '|' + '---|' * len(labels),
              '| ' + ' | '.join(fmt(np.mean([by[(s, l)]['cpu'] for s in MOVING if by[(s, l)]['cpu']]), 4)
                                for l in labels) + ' |']
    return lines


def cmd_wind(args):
    labels = args.labels.split(',')
    circles = args.circles.split(',') if args.circles else CIRCLES
    jobs = [(s, l, seed, WIND) for s in circles for l in labels
            for seed in range(args.seeds if l.startswith('preview_mpc') else args.baseline_seeds)]
    results = _pool(jobs, args.workers)
    lines = ['## Circles in wind %s, %d seeds: e_mu [m] (ground truth vs held waypoint) mean / worst; '
             '(truth vs continuous reference) mean / worst' % (WIND, args.seeds), '',
             '| scenario | ' + ' | '.join(labels) + ' |', '|---|' + '---|' * len(labels)]
    for s in circles + ['all circles']:
        cells = []
        for l in labels:
            rs = [r for r in results if (r['scenario'] == s or s == 'all circles') and r['label'] == l]
            ok = [r for r in rs if r['ok']]
            if not ok:
                cells.append('FAILED')
                continue
            a = [r['e_mu_truth'] for r in ok]
            b = [r['e_mu_ref'] for r in ok]
            cells.append('%s / %s; %s / %s%s' % (fmt(np.mean(a), 3), fmt(max(a), 3), fmt(np.mean(b), 3), fmt(max(b), 3),
                                                 '' if len(ok) == len(rs) else ' (%d failed)' % (len(rs) - len(ok))))
        lines.append('| %s | %s |' % (s, ' | '.join(cells)))
    return lines


def cmd_airship(args):
    labels = args.labels.split(',') if args.labels != DEFAULT_LABELS else AIRSHIP_LABELS
    results = _pool([('airship_follow', l, None, None) for l in labels], args.workers)
    by = dict((r['label'], r) for r in results)
    lines = ['## Airship tracking (scenario airship_follow: the airship of airship.yaml followed 6 m behind, 2 m '
             'below; 10 Hz waypoints from model_follower, no preview): e_mu [m] over one lap (120 s)', '',
             '| controller | truth vs held waypoint | truth vs continuous reference | estimate vs held waypoint |',
             '|---|---|---|---|']
    for l in labels:
        r = by[l]
        lines.append('| %s | %s |' % (l, ' | '.join(fmt(r.get(k), 3) for k in ('e_mu_truth', 'e_mu_ref', 'e_mu_est'))
                                      if r['ok'] else 'FAILED | - | -'))
    return lines


def cmd_cycle(args):
    lines = ['## cycle() time [ms], one run of %s per controller (same process, one after the other): process '
             'CPU time (time.process_time: preemption by other processes excluded) and wall time' % args.scenario,
             '', '| controller | cycles | rate [Hz] | CPU p50 | CPU p99 | CPU max | wall p50 | wall p99 | '
             'cycle CPU per simulated s [ms/s] |', '|---|---|---|---|---|---|---|---|---|']
    for label in ('preview_mpc', 'mpc'):
        controller, params = VARIANTS[label]
        eng = Engine(args.scenario, controller, controller_params=params)
        factory = eng._factory
        times, cpu = [], []

        def wrapped(factory=factory, times=times, cpu=cpu):
            core = factory()
            cycle = core.cycle

            def timed(t):
                t0, c0 = time.perf_counter(), time.process_time()
                out = cycle(t)
                cpu.append(time.process_time() - c0)
                times.append(time.perf_counter() - t0)
                return out
            core.cycle = timed
            return core
        eng._factory = wrapped
        res = eng.run()
        ms, cms = 1e3 * np.array(times), 1e3 * np.array(cpu)
        rate = eng.controller_node.core.RATE if label != 'mpc' else 10.0
        lines.append('| %s | %d | %g | %.3f | %.3f | %.3f | %.3f | %.3f | %.1f |' % (
            label, len(ms), rate, np.percentile(cms, 50), np.percentile(cms, 99), cms.max(), np.percentile(ms, 50),
            np.percentile(ms, 99), rate * cms.mean()))
    return lines


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('command', choices=('scenarios', 'wind', 'airship', 'cycle'))
    ap.add_argument('--workers', type=int, default=2)
    ap.add_argument('--seeds', type=int, default=10, help='wind: gust seeds of the preview MPC')
    ap.add_argument('--baseline-seeds', type=int, default=10, help='wind: gust seeds of mpc / pid')
    ap.add_argument('--labels', default=DEFAULT_LABELS,
                    help='comma-separated variants: %s (airship default: %s)' % (', '.join(VARIANTS),
                                                                                  ','.join(AIRSHIP_LABELS)))
    ap.add_argument('--scenario', default='circle_r3_v3')
    ap.add_argument('--circles', default='', help='wind: comma-separated circles (default: all six)')
    ap.add_argument('--out', default=None)
    args = ap.parse_args()
    t0 = time.time()
    lines = {'scenarios': cmd_scenarios, 'wind': cmd_wind, 'airship': cmd_airship,
             'cycle': cmd_cycle}[args.command](args)
    lines += ['', '(%s: %.0f s wall)' % (' '.join(sys.argv[1:]), time.time() - t0)]
    text = '\n'.join(lines) + '\n'
    print(text)
    if args.out:
        os.makedirs(args.out, exist_ok=True)
        with open(os.path.join(args.out, args.command + '.md'), 'w') as f:
            f.write(text)


if __name__ == '__main__':
    main()

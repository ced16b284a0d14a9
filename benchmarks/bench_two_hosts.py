#!/usr/bin/env python3
"""Benchmark: the Sphinx host / Gazebo host split across a network link, vs one host, with delay and loss.

Each mode runs the same chain through tools/two_hosts.sh (simulated Anafi + interface on the Sphinx host;
kinematic world + mirror + MPC + trajectory generator + evaluator on the Gazebo host; wall clock, rtf 1) and
the probe test/ros/two_hosts_probe.py on the Gazebo host, recording ``--window`` s of flight of the scenario
(default circle_r1_v1: 8 s hover, 2 settle periods, one measured period of 6.3 s) and its final evaluation:

* ``single host``: both launches in ONE namespace (no link) -- the baseline;
* ``two hosts (veth)``: two namespaces joined by a veth pair;
* ``two hosts + netem``: the veth pair with ``tc qdisc add ... netem delay 5ms loss 1%`` on both ends
  (reported as unavailable where the kernel has no sch_netem);
* ``two hosts, user-space link 0 ms / 0 %``: two TUN devices joined by tools/two_hosts_link.py (the link
  alone: its own cost), and ``... 5 ms / 1 %``: the same link delaying each packet 5 ms and dropping 1 %
  per direction (what netem would do, in user space).

The modes are interleaved over ``--rounds`` rounds (background load hits all alike). Per mode (pooled
rounds): ground truth arriving on the Gazebo host [Hz], its largest gap, crossing latency (the interface's
stamp on the Sphinx host -> receipt on the Gazebo host; both namespaces share this machine's clock),
mirror lag (ground-truth stamp -> the mirror's /gazebo/set_model_state received on the Gazebo host, i.e.
ground truth -> mirror across the link), its p99 added over the single host, share of samples mirrored,
MPC commands per second reaching the Sphinx host side, tracking error vs ground truth (e_mu of the measured
period), the machine's load. Writes benchmarks/results/two_hosts.md (+ the raw probe output in
two_hosts.json; --report-only rewrites the page from it).

Needs root (network namespaces) and the workspace environment (source env.bash).
Run: python benchmarks/bench_two_hosts.py [--rounds 2] [--window 24] [--scenario circle_r1_v1] [--no-write]
[--report-only] (about 5 minutes per round)
"""
import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time

from anafi_sim.numeric import fmt, median

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCRIPT = os.path.join(ROOT, 'tools', 'two_hosts.sh')
PROBE = os.path.join(ROOT, 'test', 'ros', 'two_hosts_probe.py')
RESULTS = os.path.join(ROOT, 'benchmarks', 'results', 'two_hosts.md')
RAW = os.path.join(ROOT, 'benchmarks', 'results', 'two_hosts.json')
NETEM = 'delay 5ms loss 1%'
MODES = [
    ('single host', ['--single-host']),
    ('two hosts (veth)', []),
    ('two hosts + netem %s' % NETEM, ['--netem', NETEM]),
    ('two hosts, user-space link 0 ms / 0 %', ['--userspace-link', '0,0']),
    ('two hosts, user-space link 5 ms / 1 %', ['--userspace-link', '5,1']),
]
SKIP, NO_NETEM = 77, 78


def run_mode(flags, args, log_dir):
    """One run of two_hosts.sh + probe -> (probe dict or None, status text)."""
    out = os.path.join(log_dir, 'probe.json')
    cmd = [SCRIPT, '--controller', args.controller, '--scenario', args.scenario, '--log-dir', log_dir] + flags + [
        '--', sys.executable, PROBE, '--window', str(args.window), '--wait-summary', '60', '--json', out]
    proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True,
                          timeout=args.window + 300)
    text = proc.stdout.strip().splitlines()
    if proc.returncode in (SKIP, NO_NETEM):
        return None, (text[-1] if text else 'unavailable (exit %d)' % proc.returncode)
    if proc.returncode != 0 or not os.path.exists(out):
        return None, 'failed (exit %d): %s' % (proc.returncode, ' / '.join(text[-3:]))
    with open(out) as f:
        return json.load(f), 'ok'


def runs_text(values, digits=1):
    return ', '.join(fmt(v, digits) for v in values) or '-'


def row(name, runs, base_p99):
    """One table row: medians over the runs, and each run's figure in brackets where it varies most."""
    truth = [(r.get('summary') or {}).get('truth') or {} for r in runs]
    p99 = [r['mirror_lag_ms']['p99'] for r in runs]
    added = None if median(p99) is None or base_p99 is None else median(p99) - base_p99
    return '| %s | %s | %s | %s / %s | %s (%s) | %s | %s | %s | %s (%s) | %s |' % (
        name, runs_text([r['gt_rate_hz'] for r in runs]), runs_text([r['gt_max_gap_ms'] for r in runs], 0),
        fmt(median([r['gt_latency_ms']['p50'] for r in runs])), fmt(median([r['gt_latency_ms']['p99'] for r in runs])),
        fmt(median([r['mirror_lag_ms']['p50'] for r in runs])), runs_text(p99, 0), fmt(added, 1),
        runs_text([100.0 * r['mirrored_share'] for r in runs]), runs_text([r['command_rate_hz'] for r in runs]),
        fmt(median([t.get('e_mu') for t in truth]), 3), runs_text([t.get('e_mu') for t in truth], 3),
        runs_text([r.get('load') for r in runs], 0))


def report(data):
    """The Markdown page of a run's data (dict: args, status, results, elapsed_s, date, machine)."""
    args, status, results = data['args'], data['status'], data['results']
    base = results.get(MODES[0][0]) or []
    base_p99 = median([r['mirror_lag_ms']['p99'] for r in base]) if base else None
    lines = [
        '# Sphinx host / Gazebo host across a network link',
        '',
        'Generated by `benchmarks/bench_two_hosts.py` (%s, %s) in %.0f s: scenario `%s`, controller `%s`, %d '
        'round(s), each running every mode in turn, %.0f s of flight recorded per run, wall clock (rtf 1). The two '
        '"hosts" are network namespaces on this machine (tools/two_hosts.sh), so they share its cores: the split '
        'shows the cost of the network path, not the CPU relief of a second PC (the paper\'s RTF 0.6 -> 1). Raw '
        'probe output: `two_hosts.json`.'
        % (data['date'], data['machine'], data['elapsed_s'], args['scenario'], args['controller'], args['rounds'],
           args['window']),
        '',
        '| mode | ground truth at the Gazebo host [Hz] (runs) | largest gap [ms] (runs) | crossing latency p50 / p99 '
        '[ms] | mirror lag p50 [ms] (p99 per run) | added p99 vs single host [ms] | samples mirrored [%] (runs) '
        '| MPC commands [Hz] (runs) | e_mu vs ground truth [m] (runs) | load (runs) |',
        '|---|---|---|---|---|---|---|---|---|---|',
    ]
    for name, _ in MODES:
        runs = results.get(name) or []
        if runs:
            lines.append(row(name, runs, base_p99))
        else:
            lines.append('| %s | %s | | | | | | | | |' % (name, (status.get(name) or ['not run'])[-1]))
    lines += [
        '',
        'Definitions: *ground truth at the Gazebo host* = /anafi/ground_truth/odom messages received by the probe '
        'there per second of the window (100 nominal); *largest gap* = between consecutive stamps (10 ms '
        'nominal); *crossing latency* = receipt on the Gazebo host - the interface\'s stamp (ROS time at receipt '
        'of the telemetry on the Sphinx host; one clock for both namespaces); *mirror lag* = receipt of the '
        'mirror\'s /gazebo/set_model_state on the Gazebo host - the stamp of the ground-truth sample it carries '
        '(matched by exact position): ground truth -> mirror across the link (the single host: no link); medians '
        'over the runs, p99 per run; *added p99* = median p99 - the single host\'s median p99; *samples mirrored* '
        '= matched / received ground-truth samples; *MPC commands* = /anafi/drone/rpyt per second (10 nominal); '
        'e_mu = the evaluator\'s mean tracking error vs ground truth over the measured period; *load* = 1-min '
        'load average at the end of the run (other jobs on the machine included: 2 cores).',
        '',
        'Status per mode: ' + '; '.join('%s: %s' % (name, ', '.join(sorted(set(status.get(name) or ['not run']))))
                                        for name, _ in MODES) + '.',
        '',
    ]
    return '\n'.join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--rounds', type=int, default=2)
    ap.add_argument('--window', type=float, default=24.0, help='s of flight recorded per run')
    ap.add_argument('--scenario', default='circle_r1_v1')
    ap.add_argument('--controller', default='mpc')
    ap.add_argument('--no-write', action='store_true')
    ap.add_argument('--report-only', action='store_true', help='rewrite the page from two_hosts.json, no run')
    args = ap.parse_args()
    if args.report_only:
        with open(RAW) as f:
            data = json.load(f)
    else:
        data = measure(args)
        if data is None:
            return 0
    text = report(data)
    print(text)
    if not args.no_write:
        with open(RESULTS, 'w') as f:
            f.write(text)
        if not args.report_only:
            with open(RAW, 'w') as f:
                json.dump(data, f, indent=1, sort_keys=True)
        print('wrote %s%s' % (os.path.relpath(RESULTS, ROOT), '' if args.report_only else ' and two_hosts.json'))
    return 0


def measure(args):
    tmp = tempfile.mkdtemp(prefix='bench_two_hosts_')
    results = dict((name, []) for name, _ in MODES)
    status = dict((name, []) for name, _ in MODES)
    started = time.time()
    for k in range(args.rounds):
        for i, (name, flags) in enumerate(MODES):
            if status[name] and status[name][-1] != 'ok' and '--netem' in flags:
                continue   # netem missing: once is enough
            res, text = run_mode(flags, args, os.path.join(tmp, 'r%d_m%d' % (k, i)))
            status[name].append(text)
            print('round %d, %s: %s%s' % (k + 1, name, text, '' if res is None else
                  ' (gt %.1f Hz, mirror lag p99 %s ms, e_mu %s m)' % (
                      res['gt_rate_hz'], res['mirror_lag_ms']['p99'],
                      ((res.get('summary') or {}).get('truth') or {}).get('e_mu'))), flush=True)
            if res is not None:
                res['load'] = round(os.getloadavg()[0], 1)
                results[name].append(res)
            if res is None and text.startswith('SKIP'):
                print(text)
                return None
    return {'args': vars(args), 'status': status, 'results': results, 'elapsed_s': round(time.time() - started),
            'date': time.strftime('%Y-%m-%d'),
            'machine': 'Python %s, %d CPU cores, %s' % (platform.python_version(), os.cpu_count(), platform.platform())}


if __name__ == '__main__':
    sys.exit(main())

#!/usr/bin/env python3
"""Concurrent ROS runs on one machine (not a test): each gets its own telemetry stream, folder and result.

Runs, on the machine's loopback (run it inside a network namespace of your own so that other work on the
machine is not disturbed, README "Tests"), first one run alone, then ``--copies`` of the same run started
at the same time, each on its own ROS master (as two users would):

- ``demo``: ``tools/demo.sh`` (``make demo``: the MPC on circle_r2_v1 in real time, mirror, bag, plot);
- ``engine``: ``experiment.py run --engine ros --sync --controller mpc --scenario circle_r2_v1 --out DIR``
  (lockstep, so that its result does not depend on the machine's load) with one shared ``--out DIR``.

For every run: the RESULT line's e_mu vs the estimate and vs ground truth, its folder, the telemetry port and
stream id its simulator and interface used (from the launch output), the exit status. The concurrent runs
must each be within ``--tolerance`` (15 %) of the solo run's e_mu, in folders of their own, on streams of
their own. Writes benchmarks/results/concurrent_runs.md; exit 1 when a check fails.

    ip netns exec NAME python benchmarks/concurrent_runs.py [--modes demo,engine] [--copies 2]
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULT_MD = os.path.join(ROOT, 'benchmarks', 'results', 'concurrent_runs.md')
ESC = re.compile(r'\x1b\[[0-9;]*m')


def command(mode, out):
    if mode == 'demo':
        return ['bash', os.path.join(ROOT, 'tools', 'demo.sh')], dict(os.environ, HOME=out)
    return ([sys.executable, os.path.join(ROOT, 'anafi_sim', 'scripts', 'experiment.py'), 'run', '--engine', 'ros',
             '--sync', '--controller', 'mpc', '--scenario', 'circle_r2_v1', '--no-plot', '--out', out],
            dict(os.environ))


def parse(text):
    """{e_mu, e_mu_truth, folder, port, stream} of one run's output."""
    text = ESC.sub('', text)
    out = {}
    m = re.search(r'vs drone estimate \(paper\)\s+e_max [\d.]+\s+e_mu ([\d.]+)', text) or \
        re.search(r'RESULT \S+\s+ok\s+e_mu ([\d.]+)', text)
    out['e_mu'] = float(m.group(1)) if m else None
    m = re.search(r'vs ground truth\s+e_max [\d.]+\s+e_mu ([\d.]+)', text) or \
        re.search(r'e_mu ([\d.]+) m \(truth\)', text)
    out['e_mu_truth'] = float(m.group(1)) if m else None
    m = re.search(r'folder:\s+(\S+)', text) or re.search(r'run folder (\S+)', text)
    out['folder'] = m.group(1) if m else None
    m = re.search(r'telemetry on [\d.]+:(\d+) \(\d+ Hz, stream id (\d+)\)', text)
    out['port'], out['stream'] = (int(m.group(1)), int(m.group(2))) if m else (None, None)
    m = re.search(r'interface: reading the telemetry of \S+ on port (\d+), stream id (\d+)', text)
    out['interface'] = (int(m.group(1)), int(m.group(2))) if m else None
    return out


def engine_logs(folder):
    """The ROS run's launch log inside an engine run's folder (the simulator's lines are there)."""
    text = ''
    for dirpath, _, names in os.walk(folder or ''):
        for n in names:
            if n.endswith('.log'):
                with open(os.path.join(dirpath, n), errors='replace') as f:
                    text += f.read()
    return text


def run_group(mode, copies, out):
    procs = []
    for i in range(copies):
        cmd, env = command(mode, out)
        log = open(os.path.join(out, '%s_%d_%d.out' % (mode, copies, i)), 'w+')
        procs.append((subprocess.Popen(cmd, env=env, stdout=log, stderr=subprocess.STDOUT, cwd=ROOT), log))
    rows = []
    for proc, log in procs:
        code = proc.wait()
        log.seek(0)
        text = log.read()
        row = parse(text)
        if mode == 'engine' and row['port'] is None:
            row.update((k, v) for k, v in parse(engine_logs(row['folder'])).items() if k in ('port', 'stream',
                                                                                          'interface'))
        row['exit'] = code
        rows.append(row)
        log.close()
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--modes', default='demo,engine')
    ap.add_argument('--copies', type=int, default=2)
    ap.add_argument('--tolerance', type=float, default=0.15)
    args = ap.parse_args(argv)
    lines = ['# Concurrent ROS runs on one machine', '',
             'Written by `benchmarks/concurrent_runs.py` on %s (load average before: %s). One run alone, then %d '
             'started at the same time, each on its own ROS master, all on one loopback. e_mu [m] vs the drone\'s '
             'estimate / vs ground truth; "stream" = the telemetry port and stream id the simulator served and the '
             'interface read.' % (time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime()),
                                  ' '.join('%.1f' % v for v in os.getloadavg()), args.copies), '']
    ok = True
    for mode in [m.strip() for m in args.modes.split(',') if m.strip()]:
        out = tempfile.mkdtemp(prefix='concurrent_%s_' % mode)
        solo = run_group(mode, 1, out)[0]
        group = run_group(mode, args.copies, out)
        lines += ['## %s' % ('`make demo` (tools/demo.sh)' if mode == 'demo' else
                             '`experiment.py run --engine ros --sync` with one `--out`'), '',
                  '| run | exit | e_mu est | e_mu truth | vs solo | folder | stream (port, id) | interface read |',
                  '|---|---|---|---|---|---|---|---|']
        folders, streams = set(), set()
        mode_ok = True
        for label, row in [('solo', solo)] + [('concurrent %d' % (i + 1), r) for i, r in enumerate(group)]:
            ratio = None
            if row['e_mu'] is not None and solo['e_mu']:
                ratio = row['e_mu'] / solo['e_mu'] - 1.0
            lines.append('| %s | %s | %s | %s | %s | %s | %s | %s |' % (
                label, row['exit'], row['e_mu'], row['e_mu_truth'],
                '-' if ratio is None or label == 'solo' else '%+.1f %%' % (100 * ratio),
                os.path.relpath(row['folder'], out) if row['folder'] else '-',
                '%s, %s' % (row['port'], row['stream']), row['interface']))
            if label != 'solo':
                good = row['exit'] == 0 and ratio is not None and abs(ratio) <= args.tolerance and \
                    row['folder'] not in folders and (row['port'], row['stream']) not in streams and \
                    row['interface'] == (row['port'], row['stream'])
                mode_ok = mode_ok and good
                folders.add(row['folder'])
                streams.add((row['port'], row['stream']))
        lines += ['', 'Concurrent runs each within %.0f %% of the solo e_mu, in folders of their own, on streams of '
                  'their own: %s.' % (100 * args.tolerance, 'yes' if mode_ok else 'NO'), '']
        ok = ok and mode_ok
    text = '\n'.join(lines) + '\n'
    os.makedirs(os.path.dirname(RESULT_MD), exist_ok=True)
    with open(RESULT_MD, 'w') as f:
        f.write(text)
    sys.stdout.write(text)
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())

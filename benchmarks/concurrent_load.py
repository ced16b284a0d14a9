#!/usr/bin/env python3
"""Wall-clock runs under load (not a test): two ``make demo`` at once beside busy loops, against a quiet run.

One command; run it inside ``env.bash``:

    python benchmarks/concurrent_load.py [--busy 1 2] [--copies 2] [--tolerance 0.10] [--no-write]

First the job alone (``tools/demo.sh``: the MPC on circle_r2_v1 in real time, mirror, bag, plot; its own
ROS master on a free port, its own telemetry port, its own HOME and folder under a temporary directory), then
for each figure of ``--busy`` (default 1 and 2) that many busy loops (``python3 -c 'while True: pass'``,
started and ended by this script) and ``--copies`` demos started at the same time beside them. For every run:
the RESULT line's verdict (ok / disturbed: <what> / FAILED: <reason>), e_mu against the drone's estimate and
against ground truth and their deviation from the quiet run, and from the run info: the ground-truth reader's
largest wake-up lag while the scenario ran, the telemetry processes the interface's watchdog killed as hung
and the silences it waited for as starved, the simulator's achieved real-time factor. The machine's CPU model,
core count and load average (before and after each phase) are recorded with them.

A phase in which a launch could not contact the ROS master it started (the machine too loaded for roscore to
come up in roslaunch's time) is run once more, and the page says so.

Checks (the issue's): beside one busy loop every run ends ok with e_mu within ``--tolerance`` (10 %) of the
quiet run; beside two, no telemetry process killed as hung and every run ok within the tolerance, or
"disturbed" with its lag. Writes benchmarks/results/concurrent_load.md (atomically; ``--no-write``: print
only); exit 1 when a check fails.
"""
import argparse
import os
import re
import signal
import subprocess
import sys
import tempfile
import time

from anafi_sim import processes, run_files

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULT_MD = os.path.join(ROOT, 'benchmarks', 'results', 'concurrent_load.md')
ESC = re.compile(r'\x1b\[[0-9;]*m')
BUSY_LOOP = [sys.executable, '-c', 'while True: pass']


def parse(text):
    """{status, e_mu, e_mu_truth, info} of one demo's output (None where absent)."""
    text = ESC.sub('', text)
    out = {}
    m = re.search(r'^RESULT \S+\s+\((.*)\)\s*$', text, re.M)
    out['status'] = m.group(1) if m else 'no RESULT line'
    if not m and 'could not contact master' in text:
        out['status'] = 'no run: roslaunch could not contact the master it started'
    m = re.search(r'vs drone estimate \(paper\)\s+e_max \S+\s+e_mu ([\d.]+)', text)
    out['e_mu'] = float(m.group(1)) if m else None
    m = re.search(r'vs ground truth\s+e_max \S+\s+e_mu ([\d.]+)', text)
    out['e_mu_truth'] = float(m.group(1)) if m else None
    m = re.search(r'^\s*info:\s+(\S+)', text, re.M)
    out['info'] = m.group(1) if m else None
    out['hung_lines'] = len(re.findall(r'interface: telemetry process \S+ hung', text))
    return out


def run_info(path):
    """The run info YAML (a FAILED run's too), {} when unreadable."""
    for candidate in (path, run_files.failed_name(path) if path else None):
        if candidate and os.path.isfile(candidate):
            data = run_files.read_yaml(candidate, tolerant=True)
            return data if isinstance(data, dict) else {}
    return {}


def run_group(copies, out, tag):
    """``copies`` demos at once, each with its own HOME under ``out``; their rows."""
    started = []
    for i in range(copies):
        home = os.path.join(out, '%s_%d' % (tag, i))
        os.makedirs(home)
        log = os.path.join(home, 'demo.out')
        proc = processes.start(['bash', os.path.join(ROOT, 'tools', 'demo.sh')], env=dict(os.environ, HOME=home),
                               log=log, cwd=ROOT)
        started.append((proc, log))
    rows = []
    for proc, log in started:
        code = proc.wait()
        try:
            os.killpg(proc.pid, signal.SIGKILL)     # anything of its launch left in its session
        except OSError:
            pass
        with open(log, errors='replace') as f:
            row = parse(f.read())
        info = run_info(row['info'])
        row.update(exit=code, log=log, reader_lag=info.get('reader_lag_max_s'), hangs=info.get('interface_hangs'),
                   starved=info.get('interface_starved'), rtf=info.get('achieved_rtf'),
                   disturbed=info.get('disturbed') or '')
        rows.append(row)
    return rows


def start_busy(n):
    return [subprocess.Popen(BUSY_LOOP, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL) for _ in range(n)]


def stop_busy(procs):
    for p in procs:
        p.kill()
        p.wait()


def deviation(row, quiet, key):
    if row.get(key) is None or not quiet.get(key):
        return None
    return row[key] / quiet[key] - 1.0


def verdict(row, quiet, busy, tolerance):
    """'' when the run passes the issue's check for ``busy`` loops, else why not."""
    devs = [deviation(row, quiet, k) for k in ('e_mu', 'e_mu_truth')]
    within = all(d is not None and abs(d) <= tolerance for d in devs)
    hung = (row['hangs'] or 0) > 0 or row['hung_lines'] > 0
    status = row['status']
    if busy <= 1:
        if status != 'ok':
            return 'not ok'
        return '' if within else 'e_mu off by more than %.0f %%' % (100 * tolerance)
    if hung:
        return 'telemetry process killed as hung'
    if status.startswith('disturbed') and row.get('reader_lag') is not None:
        return ''
    if status == 'ok' and within:
        return ''
    return 'neither ok within %.0f %% nor disturbed with its lag' % (100 * tolerance)


def fmt(v, pattern='%.3f'):
    return '-' if v is None else pattern % v


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--busy', type=int, nargs='+', default=[1, 2], help='busy loops beside the runs, per phase')
    ap.add_argument('--copies', type=int, default=2, help='demos started at once per phase')
    ap.add_argument('--tolerance', type=float, default=0.10, help='e_mu against the quiet run')
    ap.add_argument('--no-write', action='store_true', help='print only; do not write the results page')
    args = ap.parse_args(argv)
    out = tempfile.mkdtemp(prefix='concurrent_load_')
    phases = []
    load0 = os.getloadavg()
    quiet = run_group(1, out, 'quiet')[0]
    phases.append(('quiet: the job alone', 0, load0, os.getloadavg(), [quiet]))
    for n in args.busy:
        before = os.getloadavg()
        busy = start_busy(n)
        attempts = []
        try:
            while len(attempts) < 2:    # a launch whose ROS master did not start measured nothing: once more
                rows = run_group(args.copies, out, 'busy%d_%d' % (n, len(attempts) + 1))
                attempts.append(rows)
                if not any(r['status'].startswith('no run') for r in rows):
                    break
        finally:
            stop_busy(busy)
        title = '%d at once beside %d busy loop%s' % (args.copies, n, '' if n == 1 else 's')
        if len(attempts) > 1:
            title += ' (second attempt: in the first, %d of the launches could not contact the master they ' \
                'started)' % sum(r['status'].startswith('no run') for r in attempts[0])
        phases.append((title, n, before, os.getloadavg(), attempts[-1]))
    cores = os.cpu_count()
    lines = ['# Wall-clock runs under load', '',
             'Written by `python benchmarks/concurrent_load.py%s` on %s: %s, %d cores. Shared machine: the load '
             'average (1, 5, 15 min) before and after each phase is the other work on it plus ours. Each run is '
             '`tools/demo.sh` (`make demo`: MPC on circle_r2_v1 in real time) on its own master, ports and folder. '
             'e_mu [m] against the drone\'s estimate (the paper\'s metric) / against ground truth, and its deviation '
             'from the quiet run; "reader lag": the ground-truth reader\'s largest wake-up lag while the scenario '
             'ran (disturbed beyond 0.5 s); "hung / starved": telemetry processes the interface killed as hung / '
             'silences it waited for as starved (whole run); "rtf": the simulator\'s achieved real-time factor.'
             % (' '.join([''] + (argv if argv is not None else sys.argv[1:])), time.strftime('%Y-%m-%d %H:%M UTC',
                                                                                        time.gmtime()),
                processes.cpu_model(), cores), '']
    ok = True
    for title, n, before, after, rows in phases:
        lines += ['## %s' % title, '',
                  'Load average before %s, after %s.' % (' '.join('%.1f' % v for v in before),
                                                         ' '.join('%.1f' % v for v in after)), '',
                  '| run | exit | RESULT | e_mu est | vs quiet | e_mu truth | vs quiet | reader lag [s] '
                  '| hung / starved | rtf | check |', '|---|---|---|---|---|---|---|---|---|---|---|']
        for i, row in enumerate(rows):
            problem = '' if n == 0 else verdict(row, quiet, n, args.tolerance)
            ok = ok and not problem
            dev = [deviation(row, quiet, k) for k in ('e_mu', 'e_mu_truth')]
            lines.append('| %s | %s | %s | %s | %s | %s | %s | %s | %s / %s | %s | %s |' % (
                'quiet' if n == 0 else 'run %d' % (i + 1), row['exit'], row['status'].replace('|', '/'),
                fmt(row['e_mu']), '-' if n == 0 else fmt(None if dev[0] is None else 100 * dev[0], '%+.1f %%'),
                fmt(row['e_mu_truth']), '-' if n == 0 else fmt(None if dev[1] is None else 100 * dev[1], '%+.1f %%'),
                fmt(row['reader_lag']), fmt(row['hangs'], '%d'), fmt(row['starved'], '%d'), fmt(row['rtf'], '%.2f'),
                'reference' if n == 0 else (problem or 'pass')))
        lines.append('')
    lines += ['Checks: beside one busy loop every run ok with e_mu (estimate and ground truth) within %.0f %% of '
              'the quiet run; beside two, no telemetry process killed as hung and every run ok within %.0f %% or '
              '"disturbed" with its lag: %s. The runs\' outputs: `%s`.' % (100 * args.tolerance, 100 * args.tolerance,
                                                                          'yes' if ok else 'NO', out), '']
    text = '\n'.join(lines)
    sys.stdout.write(text)
    if not args.no_write:
        run_files.atomic_write_text(RESULT_MD, text)
        sys.stdout.write('written: %s\n' % RESULT_MD)
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())

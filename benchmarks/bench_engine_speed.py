#!/usr/bin/env python3
"""The in-process engine against a reference revision of itself (default: where this branch left main), side by
side in one run: the paper's batch (16 scenarios x MPC, PID, preview MPC = 48 runs) with each revision's code,
interleaved (A B, B A, ...), and its 288 figures (e_max, e_mu, e_sigma vs estimate and vs ground truth per run)
compared bit for bit -> benchmarks/results/engine_speed.{md,yaml} (with ``--update``; else a run folder).

Stage: benchmark (not a timed test). Each measurement is one child process (this script with ``--child``) that
imports the revision's anafi_sim / anafi_control / anafi_lab (the reference: ``git archive REV`` into a temporary
folder first on PYTHONPATH; the candidate: this checkout) and runs the batch's runs one after another in that one
process (``--mode engine``: the engine alone, no files, no plots: the single-process speed) or the whole batch
as ``make bench`` runs it (``--mode batch``: ``experiment.py batch`` with ``--workers`` processes, files and
plots). The figures are the engine's unrounded floats (``repr``) and a hash of every run's whole reference log
(every sample of waypoint, estimate and truth); the rounded ones of the committed batch
(benchmarks/results/inprocess/experiments.yaml) are compared too. Timing: wall and CPU seconds (user + system of
the child and its workers); the machine is shared, so the ratio of A and B taken in the same rounds is the
figure, with the load beside it.

    python benchmarks/bench_engine_speed.py [--reference REV] [--repeats 2] [--mode engine|batch|both]
        [--workers 2] [--runs NAME,...] [--update]
"""
import argparse
import collections
import datetime
import hashlib
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, 'benchmarks', 'results')
PACKAGES = ('anafi_sim', 'anafi_control', 'anafi_lab')
CONTROLLERS = ('mpc', 'pid', 'preview_mpc')
SOURCES = ('estimate', 'truth')
STATS = ('e_max', 'e_mu', 'e_sigma')


# ------------------------------------------------------------------------------------------------ child
def child(args):
    """Run the batch's runs in this process (mode engine) and print one JSON line: figures and times."""
    import numpy as np
    from anafi_lab.engine import runs
    from anafi_lab.engine.engine import Engine
    only = set(args.runs.split(',')) if args.runs else None
    out = collections.OrderedDict()
    wall0, cpu0 = time.perf_counter(), time.process_time()
    for task in runs.batch_tasks(controllers=CONTROLLERS):
        name = runs.task_name(task)
        if only and name not in only:
            continue
        result = Engine(task['scenario'], task['controller'], name=name).run()
        ev = result.evaluation
        digest = hashlib.sha256(ev.full_log.time_ns.tobytes())
        for key in sorted(ev.full_log.columns):
            digest.update(key.encode())
            digest.update(np.ascontiguousarray(ev.full_log.columns[key]).tobytes())
        out[name] = {'figures': [repr(float(getattr(getattr(ev, src), k))) for src in SOURCES for k in STATS],
                     'rounded': [result.summary[src][k] for src in SOURCES for k in STATS],
                     'log': digest.hexdigest(), 'ok': result.ok}
    print(json.dumps({'wall_s': time.perf_counter() - wall0, 'cpu_s': time.process_time() - cpu0, 'runs': out}))


# ------------------------------------------------------------------------------------------------ parent
def reference_tree(rev, folder):
    """``git archive REV`` of the packages into ``folder``; returns the commit."""
    commit = subprocess.check_output(['git', '-C', ROOT, 'rev-parse', rev], text=True).strip()
    archive = subprocess.Popen(['git', '-C', ROOT, 'archive', '--format=tar', commit] + list(PACKAGES),
                               stdout=subprocess.PIPE)
    subprocess.check_call(['tar', '-x', '-C', folder], stdin=archive.stdout)
    if archive.wait() != 0:
        raise RuntimeError('git archive %s failed' % rev)
    return commit


def default_reference():
    """Where this branch left main (git merge-base HEAD main), else HEAD."""
    try:
        return subprocess.check_output(['git', '-C', ROOT, 'merge-base', 'HEAD', 'main'], text=True,
                                       stderr=subprocess.DEVNULL).strip()
    except subprocess.CalledProcessError:
        return 'HEAD'


def _env(src):
    env = dict(os.environ)
    if src:
        env['PYTHONPATH'] = src + os.pathsep + env.get('PYTHONPATH', '')
    return env


def _children_cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def measure_engine(src, runs_arg):
    """One child in mode engine with the packages of ``src`` (None: this checkout): its JSON, load before."""
    cmd = [sys.executable, os.path.abspath(__file__), '--child']
    if runs_arg:
        cmd += ['--runs', runs_arg]
    load = os.getloadavg()[0]
    out = subprocess.check_output(cmd, env=_env(src), cwd=tempfile.gettempdir(), text=True)
    data = json.loads(out.strip().splitlines()[-1])
    data['load'] = load
    return data


def measure_batch(src, workers, tmp):
    """``experiment.py batch`` (files and plots, ``workers`` processes) with the packages of ``src``: wall, CPU of
    the child and its workers, the load before, the records' rounded figures."""
    out = tempfile.mkdtemp(prefix='batch_', dir=tmp)
    script = os.path.join(src or ROOT, 'anafi_lab', 'cli', 'experiment.py')
    load = os.getloadavg()[0]
    cpu0, wall0 = _children_cpu(), time.perf_counter()
    subprocess.check_call([sys.executable, script, 'batch', '--out', out, '--runs-dir', os.path.join(out, 'runs'),
                           '--workers', str(workers)], env=_env(src), cwd=tmp, stdout=subprocess.DEVNULL,
                          stderr=subprocess.DEVNULL)
    wall, cpu = time.perf_counter() - wall0, _children_cpu() - cpu0
    from anafi_sim.run_files import read_yaml
    records = read_yaml(os.path.join(out, 'experiments.yaml'))['records']
    figures = dict(('%s_%s' % (r['scenario'], r['controller']),
                    [r['summary'][s][k] for s in SOURCES for k in STATS]) for r in records)
    shutil.rmtree(out, ignore_errors=True)
    return {'wall_s': wall, 'cpu_s': cpu, 'load': load, 'figures': figures}


def committed_figures():
    """Rounded figures of the committed in-process batch per run name."""
    from anafi_sim.run_files import read_yaml
    data = read_yaml(os.path.join(RESULTS, 'inprocess', 'experiments.yaml'), {}) or {}
    return dict(('%s_%s' % (r['scenario'], r['controller']), [r['summary'][s][k] for s in SOURCES for k in STATS])
                for r in data.get('records', []) if r.get('summary'))


def compare(a_runs, b_runs):
    """(figures compared, figures that differ, logs that differ, [names that differ])."""
    n = diff = logs = 0
    names = []
    for name in sorted(set(a_runs) | set(b_runs)):
        a, b = a_runs.get(name), b_runs.get(name)
        if a is None or b is None:
            names.append(name)
            continue
        d = sum(1 for x, y in zip(a['figures'], b['figures']) if x != y)
        n += len(a['figures'])
        diff += d
        logs += a['log'] != b['log']
        if d or a['log'] != b['log']:
            names.append(name)
    return n, diff, logs, names


def ratio_stats(pairs):
    ratios = sorted(a / b for a, b in pairs if b > 0)
    if not ratios:
        return None
    return {'min': round(ratios[0], 2), 'median': round(ratios[len(ratios) // 2] if len(ratios) % 2 else
                                                        0.5 * (ratios[len(ratios) // 2 - 1] + ratios[len(ratios) // 2]), 2),
            'max': round(ratios[-1], 2), 'of_sums': round(sum(a for a, _ in pairs) / sum(b for _, b in pairs), 2)}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--reference', default=None, help='the revision to compare with (default: git merge-base '
                                                         'HEAD main)')
    parser.add_argument('--repeats', type=int, default=2, help='rounds of A and B (each round both, order alternating)')
    parser.add_argument('--mode', choices=('engine', 'batch', 'both'), default='engine')
    parser.add_argument('--workers', type=int, default=2, help='worker processes of --mode batch')
    parser.add_argument('--runs', default='', help='only these runs (SCENARIO_CONTROLLER,...; mode engine)')
    parser.add_argument('--update', action='store_true', help='write the committed results page')
    parser.add_argument('--child', action='store_true', help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args)
        return 0
    from anafi_sim import processes, run_files
    rev = args.reference or default_reference()
    tmp = tempfile.mkdtemp(prefix='anafi_engine_speed_')
    try:
        ref_src = os.path.join(tmp, 'reference')
        os.makedirs(ref_src)
        commit = reference_tree(rev, ref_src)
        head = subprocess.check_output(['git', '-C', ROOT, 'rev-parse', 'HEAD'], text=True).strip()
        dirty = bool(subprocess.check_output(['git', '-C', ROOT, 'status', '--porcelain', '--'] + list(PACKAGES),
                                             text=True).strip())
        load0 = os.getloadavg()[0]
        rounds = {'engine': [], 'batch': []}
        modes = ('engine', 'batch') if args.mode == 'both' else (args.mode,)
        for i in range(args.repeats):
            order = (('A', ref_src), ('B', None)) if i % 2 == 0 else (('B', None), ('A', ref_src))
            for mode in modes:
                entry = {}
                for label, src in order:
                    if mode == 'engine':
                        entry[label] = measure_engine(src, args.runs)
                    else:
                        entry[label] = measure_batch(src, args.workers, tmp)
                    print('round %d %s %s: %.1f s wall, %.1f s CPU (load %.1f)' % (
                        i + 1, mode, 'reference' if label == 'A' else 'this checkout', entry[label]['wall_s'],
                        entry[label]['cpu_s'], entry[label]['load']), flush=True)
                rounds[mode].append(entry)
        figures = {'date': datetime.datetime.now().strftime('%Y-%m-%d %H:%M'), 'machine': processes.machine(load0),
                   'reference': commit, 'candidate': head + (' + uncommitted changes' if dirty else ''),
                   'repeats': args.repeats, 'workers': args.workers}
        committed = committed_figures()
        if rounds['engine']:
            first = rounds['engine'][0]
            n, diff, logs, names = compare(first['A']['runs'], first['B']['runs'])
            stable = all(compare(r['A']['runs'], first['A']['runs'])[1:3] == (0, 0) and
                         compare(r['B']['runs'], first['B']['runs'])[1:3] == (0, 0) for r in rounds['engine'])
            rounded_diff = sum(1 for name, run in first['B']['runs'].items() if name in committed
                               for x, y in zip(run['rounded'], committed[name]) if x != y)
            figures['engine'] = {
                'runs': len(first['B']['runs']), 'figures': n, 'figures_differing': diff, 'logs_differing': logs,
                'runs_differing': names, 'repeat_identical': stable,
                'committed_compared': sum(6 for name in first['B']['runs'] if name in committed),
                'committed_differing': rounded_diff,
                'rounds': [dict((k, {'wall_s': round(e[k]['wall_s'], 2), 'cpu_s': round(e[k]['cpu_s'], 2),
                                     'load': round(e[k]['load'], 1)}) for k in ('A', 'B')) for e in rounds['engine']],
                'speedup_wall': ratio_stats([(e['A']['wall_s'], e['B']['wall_s']) for e in rounds['engine']]),
                'speedup_cpu': ratio_stats([(e['A']['cpu_s'], e['B']['cpu_s']) for e in rounds['engine']]),
            }
        if rounds['batch']:
            first = rounds['batch'][0]
            diff = sum(1 for name in first['A']['figures'] for x, y in
                       zip(first['A']['figures'][name], first['B']['figures'].get(name, [])) if x != y)
            figures['batch'] = {
                'runs': len(first['B']['figures']), 'rounded_figures_differing': diff,
                'rounds': [dict((k, {'wall_s': round(e[k]['wall_s'], 2), 'cpu_s': round(e[k]['cpu_s'], 2),
                                     'load': round(e[k]['load'], 1)}) for k in ('A', 'B')) for e in rounds['batch']],
                'speedup_wall': ratio_stats([(e['A']['wall_s'], e['B']['wall_s']) for e in rounds['batch']]),
                'speedup_cpu': ratio_stats([(e['A']['cpu_s'], e['B']['cpu_s']) for e in rounds['batch']]),
            }
        out_dir = RESULTS if args.update else run_files.new_run_dir(os.path.join(ROOT, 'run'), 'engine-speed')
        os.makedirs(out_dir, exist_ok=True)
        run_files.write_yaml(os.path.join(out_dir, 'engine_speed.yaml'), figures)
        run_files.atomic_write_text(os.path.join(out_dir, 'engine_speed.md'), render(figures))
        print(render(figures))
        print('written: %s' % os.path.join(out_dir, 'engine_speed.md'))
        return 0 if (figures.get('engine', {}).get('figures_differing', 0) == 0 and
                     figures.get('batch', {}).get('rounded_figures_differing', 0) == 0) else 1
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def render(f):
    lines = ['# The in-process engine against its reference revision, side by side', '',
             'Generated by `benchmarks/bench_engine_speed.py` (%s), machine: %s. Reference (A): `%s`; this checkout '
             '(B): `%s`. A and B alternate within each round (A B, then B A); the machine is shared, so each '
             'round\'s ratio A / B is the figure, the load (1-min average when the measurement started) beside '
             'each time.' % (f['date'], f['machine'], f['reference'][:12], f['candidate'][:12]
                             + (' + uncommitted changes' if 'uncommitted' in f['candidate'] else '')), '']
    e = f.get('engine')
    if e:
        lines += ['## The engine alone: one process, %d runs, no files' % e['runs'], '',
                  '**Figures: %d of %d differ** (unrounded e_max, e_mu, e_sigma vs estimate and vs truth per run), '
                  '%d of %d reference logs differ (a hash of every sample of every column); the same in every '
                  'round: %s. Against the committed batch (benchmarks/results/inprocess/experiments.yaml, 4 '
                  'decimals): %d of %d differ.' % (
                      e['figures_differing'], e['figures'], e['logs_differing'], e['runs'],
                      'yes' if e['repeat_identical'] else 'no', e['committed_differing'], e['committed_compared']), '',
                  '| round | A wall [s] | B wall [s] | A / B wall | A CPU [s] | B CPU [s] | A / B CPU | load at A, B |',
                  '|---|---|---|---|---|---|---|---|']
        for i, r in enumerate(e['rounds']):
            lines.append('| %d | %.1f | %.1f | %.2f | %.1f | %.1f | %.2f | %.1f, %.1f |' % (
                i + 1, r['A']['wall_s'], r['B']['wall_s'], r['A']['wall_s'] / r['B']['wall_s'], r['A']['cpu_s'],
                r['B']['cpu_s'], r['A']['cpu_s'] / r['B']['cpu_s'], r['A']['load'], r['B']['load']))
        lines += ['', 'Speed-up (A / B): wall %s; CPU %s (min / median / max over the rounds; of the sums).' % (
            _ratios(e['speedup_wall']), _ratios(e['speedup_cpu'])), '']
    b = f.get('batch')
    if b:
        lines += ['## The whole batch as `make bench` runs it: %d runs on %d worker processes, files and plots'
                  % (b['runs'], f['workers']), '',
                  'Rounded figures (the records\' summaries) differing between A and B: %d.' % b['rounded_figures_differing'],
                  '', '| round | A wall [s] | B wall [s] | A / B wall | A CPU [s] | B CPU [s] | A / B CPU | load at A, B |',
                  '|---|---|---|---|---|---|---|---|']
        for i, r in enumerate(b['rounds']):
            lines.append('| %d | %.1f | %.1f | %.2f | %.1f | %.1f | %.2f | %.1f, %.1f |' % (
                i + 1, r['A']['wall_s'], r['B']['wall_s'], r['A']['wall_s'] / r['B']['wall_s'], r['A']['cpu_s'],
                r['B']['cpu_s'], r['A']['cpu_s'] / r['B']['cpu_s'], r['A']['load'], r['B']['load']))
        lines += ['', 'Speed-up (A / B): wall %s; CPU %s.' % (_ratios(b['speedup_wall']), _ratios(b['speedup_cpu'])),
                  '']
    return '\n'.join(lines)


def _ratios(s):
    return 'n/a' if not s else '%.2f / %.2f / %.2f x (%.2f x)' % (s['min'], s['median'], s['max'], s['of_sums'])


if __name__ == '__main__':
    sys.exit(main())

"""The fleet benchmark's results (benchmarks/results/fleet.json) -> figures and text: no ROS, no processes.

One definition of *holds real time* (``HOLD``), the summary of every size and layout across its repeated runs
(min / median / max), the largest fleet holding real time per layout, the per-drone CPU the fleet cap is
derived from (``cap_cpu_per_drone``), and the Markdown of benchmarks/results/fleet.md and of the generated
block in docs/fleet.md (Jinja2 templates beside this file: fleet.md.j2, fleet_docs.md.j2).

fleet.json: {'format': 2, 'fleet', 'settle' [s], 'duration' [s], 'repeats', 'sizes', 'layouts', 'machine':
{'date', 'python', 'cores', 'cpu_model'}, 'core_cost', 'runs': [one measurement window each: 'layout', 'n',
'repeat', 'drones' {name: {'rtf', 'truth_hz', 'mirror_hz', ...}}, 'roles' {role: [% of one core, processes]},
'busy' [%], 'other_jobs' [% of one core], 'load_before', 'load_after', 'bench_cpu', 'startup_s', 'wall',
'largest_processes' [[role, % of one core], largest first; runs before it was recorded have none]; or
'error' when the fleet never flew]}. The older format ({'results': [...]}, one run per size, per-drone layout,
no machine facts) loads as repeats = 1.
"""
import json
import math
import os
import re

import jinja2

from anafi_sim.mission import fleet_realtime
from anafi_sim.numeric import median

HERE = os.path.dirname(os.path.abspath(__file__))
#: a fleet holds real time when, in every run, every drone has at least these: simulator RTF (sim time / wall
#: time), ground-truth rate [Hz] (interface: samples published / wall time), mirror rate [Hz] (samples sent)
#: (anafi_sim.mission.fleet_realtime's thresholds, which a fleet host reports against on /diagnostics, at 100 Hz)
HOLD = {'rtf': fleet_realtime.MIN_RTF, 'truth_hz': round(100.0 * fleet_realtime.MIN_RATE_FRACTION, 6),
        'mirror_hz': round(100.0 * fleet_realtime.MIN_RATE_FRACTION, 6)}
HOLD_TEXT = ("every drone's RTF >= %.2f, ground truth >= %g Hz and mirror sent >= %g Hz"
             % (HOLD['rtf'], HOLD['truth_hz'], HOLD['mirror_hz']))
LAYOUTS = ('per_drone', 'shared')
#: roles counted once per drone (per_drone layout) and roles the fleet shares; a shared layout adds 'host NAME'
PER_DRONE_ROLES = ('simulator', 'telemetry CLI', 'interface', 'mirror', 'controller', 'generator', 'evaluator')
SHARED_ROLES = ('world', 'roslaunch', 'master + rosout')
#: [% of one core] of other processes during a window: above it, a run measures the machine
OTHER_JOBS_LIMIT = 30.0
#: the generated block of docs/fleet.md
DOCS_BEGIN = '<!-- fleet-benchmark:begin -->'
DOCS_END = '<!-- fleet-benchmark:end -->'
#: the spread's keys: a run's figure -> its name in the tables
SPREAD_KEYS = ('rtf_min', 'truth_min', 'mirror_min', 'cpu_total', 'cpu_per_drone', 'largest_process')


#: command-line substring -> role (the first that matches); a shared layout's host: ``host_role``
ROLES = (('anafi_sim_node.py', 'simulator'), ('tlm_data_logger.py', 'telemetry CLI'),
         ('interface_node.py', 'interface'), ('gazebo_mirror_node.py', 'mirror'),
         ('controller_node.py', 'controller'), ('pid_', 'controller'),
         ('trajectory_generator.py', 'generator'), ('model_follower.py', 'generator'),
         ('evaluator.py', 'evaluator'), ('kinematic_world_node.py', 'world'), ('fleet_launcher.py', 'roslaunch'),
         ('roslaunch', 'roslaunch'), ('rosmaster', 'master + rosout'), ('rosout', 'master + rosout'))
HOST_SCRIPT = 'fleet_host.py'


def role_of_cmdline(words):
    """The role a process counts under, from its command line (list of words): ``host NAME`` for
    ``fleet_host.py ... __name:=NAME`` (the shared layout: one role of every drone), else ``ROLES``, else 'other'."""
    cmd = ' '.join(words)
    if HOST_SCRIPT in cmd:
        names = [w[len('__name:='):] for w in words if w.startswith('__name:=')]
        return 'host %s' % names[-1] if names else 'host'
    for key, role in ROLES:
        if key in cmd:
            return role
    return 'other'


def _finite(v):
    return v is not None and not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v)


def load(path):
    """fleet.json as a dict in the current format (an older file: one run per size, layout per_drone)."""
    with open(path) as f:
        return normalize(json.load(f))


def normalize(data):
    """The current format of a results dict (the older {'results': [...]} -> runs with repeat 0)."""
    if 'runs' in data:
        return data
    runs = [dict(r, layout='per_drone', repeat=0) for r in data.get('results', [])]
    return {'format': 1, 'fleet': data.get('fleet'), 'settle': data.get('settle'), 'duration': data.get('duration'),
            'repeats': 1, 'sizes': sorted(set(r['n'] for r in runs)), 'layouts': ['per_drone'], 'machine': {},
            'core_cost': data.get('core_cost'), 'runs': runs}


def drone_values(run, key):
    """A figure of every drone of a run (drones without figures left out)."""
    return [f[key] for f in run.get('drones', {}).values() if f and key in f]


def _min(run, key):
    vals = [v for v in drone_values(run, key) if _finite(v)]
    return min(vals) if vals else None


def _max(run, key):
    vals = [v for v in drone_values(run, key) if _finite(v)]
    return max(vals) if vals else None


def cpu_total(run):
    """CPU [% of one core] of every process of the fleet (launch tree and roscore) over the window."""
    return sum(v[0] for v in run.get('roles', {}).values()) if run.get('roles') else None


def other_jobs(run, cores=None):
    """CPU [% of one core] outside the fleet and this script: as recorded, or busy x cores - fleet - bench."""
    if 'other_jobs' in run:
        return run['other_jobs']
    if not cores or 'busy' not in run:
        return None
    return max(0.0, run['busy'] * cores - cpu_total(run) - run.get('bench_cpu', 0.0))


def run_holds(run):
    """True when every drone of one run held real time (``HOLD``); False for a run without figures."""
    figs = list(run.get('drones', {}).values())
    if run.get('error') or not figs or any(not f for f in figs):
        return False
    return all(_finite(f.get(k)) and f[k] >= v for f in figs for k, v in HOLD.items())


def run_figures(run):
    """The figures of one run the summary spreads: minima over the drones, CPU total and per drone."""
    total = cpu_total(run)
    largest = (run.get('largest_processes') or [[None, None]])[0]
    return {'rtf_min': _min(run, 'rtf'), 'truth_min': _min(run, 'truth_hz'), 'mirror_min': _min(run, 'mirror_hz'),
            'cpu_total': total, 'cpu_per_drone': None if total is None else total / run['n'],
            'largest_process': largest[1], 'largest_role': largest[0], 'holds': run_holds(run)}


def spread(values):
    """(min, median, max) of the finite values, None when there is none."""
    v = [x for x in values if _finite(x)]
    return (min(v), median(v), max(v)) if v else None


def summary(data):
    """One row per (layout, size): its runs, 'holds' (every run holds), the spread of each of SPREAD_KEYS and the
    median CPU per role [% of one core]."""
    rows = []
    for layout in data['layouts']:
        for n in sorted(set(r['n'] for r in data['runs'] if r['layout'] == layout)):
            runs = sorted((r for r in data['runs'] if r['layout'] == layout and r['n'] == n),
                          key=lambda r: r['repeat'])
            figs = [run_figures(r) for r in runs]
            roles = sorted(set(k for r in runs for k in r.get('roles', {})))
            roles_largest = sorted(set(f['largest_role'] for f in figs if f['largest_role']))
            rows.append({'layout': layout, 'n': n, 'runs': runs, 'figures': figs, 'largest_roles': roles_largest,
                         'holds': bool(runs) and all(f['holds'] for f in figs),
                         'held': sum(1 for f in figs if f['holds']),
                         'spread': dict((k, spread([f[k] for f in figs])) for k in SPREAD_KEYS),
                         'roles': dict((ro, median([r['roles'][ro][0] for r in runs if ro in r.get('roles', {})]))
                                       for ro in roles)})
    return rows


def headline(data, rows=None):
    """Per layout: the largest size that holds real time in every run (None: none) and its summary row."""
    rows = summary(data) if rows is None else rows
    out = []
    for layout in data['layouts']:
        mine = [r for r in rows if r['layout'] == layout]
        held = [r for r in mine if r['holds']]
        best = max(held, key=lambda r: r['n']) if held else None
        failing = [r['n'] for r in mine if not r['holds'] and (best is None or r['n'] > best['n'])]
        out.append({'layout': layout, 'row': best, 'n': best['n'] if best else None,
                    'sizes': [r['n'] for r in mine], 'failing_above': failing,
                    'cpu_per_drone': cap_cpu_per_drone(data, layout, rows),
                    'failing_per_core': cap_failing_per_core(data, layout, rows)})
    return out


def cap_failing_per_core(data, layout, rows=None):
    """[drones per core] the smallest size not holding real time above the largest one holding, divided by the
    measuring machine's cores (anafi_sim.launch_check.FAILING_PER_CORE; None: none such, or no cores recorded)."""
    rows = summary(data) if rows is None else rows
    mine = [r for r in rows if r['layout'] == layout]
    held = [r['n'] for r in mine if r['holds']]
    failing = [r['n'] for r in mine if not r['holds'] and (not held or r['n'] > max(held))]
    cores = (data.get('machine') or {}).get('cores')
    if not failing or not cores:
        return None
    return round(min(failing) / float(cores), 3)


def cap_cpu_per_drone(data, layout, rows=None):
    """[cores] the CPU of one drone the fleet cap divides the cores by: the median over the runs of CPU per
    drone at the largest size holding real time (3 decimals; None when no size holds)."""
    rows = summary(data) if rows is None else rows
    held = [r for r in rows if r['layout'] == layout and r['holds']]
    if not held:
        return None
    best = max(held, key=lambda r: r['n'])
    return round(best['spread']['cpu_per_drone'][1] / 100.0, 3)


def host_kind(role):
    """'host fleet_ground_truth_2' -> 'fleet_ground_truth' (a host of the shared layout's split); None otherwise."""
    if not role.startswith('host '):
        return None
    name = role[len('host '):]
    base, _, number = name.rpartition('_')
    return base if number.isdigit() and base else name


def host_cpu_per_drone(data, rows=None):
    """[cores] {host kind: its CPU per drone} of the shared layout at the largest size holding real time (the
    median over the runs of the hosts of that kind together over N; 3 decimals), the figures the split of the
    hosts comes from (launch_check.drones_per_host); None when no size holds."""
    rows = summary(data) if rows is None else rows
    held = [r for r in rows if r['layout'] == 'shared' and r['holds']]
    if not held:
        return None
    best = max(held, key=lambda r: r['n'])
    per_run = []
    for run in best['runs']:
        kinds = {}
        for role, (cpu, _count) in run.get('roles', {}).items():
            kind = host_kind(role)
            if kind:
                kinds[kind] = kinds.get(kind, 0.0) + cpu
        per_run.append(kinds)
    kinds = sorted(set(k for r in per_run for k in r))
    return dict((k, round(median([r.get(k, 0.0) for r in per_run]) / 100.0 / best['n'], 4)) for k in kinds) or None


def _cell_text(text):
    return str(text).replace('|', '/').replace('\n', ' ')


def processes_markdown(data, budget=None):
    """The per-process page of shared-layout runs (bench_fleet.py --processes-page): per run the machine's load,
    the split of the hosts, whether it held real time and every process with its CPU [% of one core], the hosts
    against the budget of one host (launch_check.HOST_CORE_BUDGET)."""
    if budget is None:
        from anafi_sim.launch_check import HOST_CORE_BUDGET as budget
    machine = data.get('machine') or {}
    cores = machine.get('cores')
    lines = ['# Per-process CPU of the shared layout', '',
             'Measured by `%s` on %s, %s cores (Python %s, %s; load average at the start %s). Figures of that '
             'machine and that load, in %% of one core over %.0f s of wall time per run; a host process may take '
             'at most %.0f %% of a core (`launch_check.HOST_CORE_BUDGET`), the split of the hosts comes from this '
             'machine\'s figures (`launch_check.machine_drones_per_host`). Holds real time: %s.'
             % (data.get('command', 'benchmarks/bench_fleet.py'), machine.get('cpu_model', '?'), cores,
                machine.get('python', '?'), machine.get('date', '?'),
                ' / '.join('%.1f' % v for v in machine.get('load_start', [])) or '?', data.get('duration', 0),
                100.0 * budget, HOLD_TEXT), '',
             '| N | run | holds | hosts split by | load (1 min) before / after | other jobs [% core] | largest host '
             '[% core] | within the budget |', '|---|---|---|---|---|---|---|---|']
    runs = [r for r in data['runs'] if r.get('layout') == 'shared' and 'error' not in r]
    for r in data['runs']:
        if r.get('layout') == 'shared' and 'error' in r:
            lines.append('| %d | %d | no: %s | - | - | - | - | - |' % (r['n'], r['repeat'] + 1,
                                                                   _cell_text(str(r['error']).splitlines()[0])))
    for r in runs:
        hosts = [(role, cpu) for role, cpu in r.get('processes', []) if role.startswith('host ')]
        largest = max(hosts, key=lambda h: h[1]) if hosts else None
        split = ', '.join('%s %d' % kv for kv in sorted((r.get('drones_per_host') or {}).items())) or '-'
        lines.append('| %d | %d | %s | %s | %.1f / %.1f | %s | %s | %s |' % (
            r['n'], r['repeat'] + 1, 'yes' if run_holds(r) else 'no', split, r['load_before'][0],
            r['load_after'][0], fmt(other_jobs(r, cores), 0),
            '%s %.1f' % (largest[0][len('host '):], largest[1]) if largest else '-',
            '-' if not largest else ('yes' if largest[1] <= 100.0 * budget else 'no')))
    for r in runs:
        lines += ['', '## N = %d, run %d' % (r['n'], r['repeat'] + 1), '', '| process | % of one core |', '|---|---|']
        lines += ['| %s | %.1f |' % (role, cpu) for role, cpu in r.get('processes', [])
                  if role.startswith('host ') or cpu >= 1.0]
        small = [cpu for role, cpu in r.get('processes', []) if not role.startswith('host ') and cpu < 1.0]
        if small:
            lines.append('| %d other processes under 1 %% each | %.1f together |' % (len(small), sum(small)))
    return '\n'.join(lines) + '\n'


def role_order(rows):
    """The roles seen, per-drone roles first, then the shared layout's hosts, the shared roles, 'other'."""
    seen = set(ro for r in rows for ro in r['roles'])
    hosts = sorted(ro for ro in seen if ro.startswith('host '))
    return [ro for ro in PER_DRONE_ROLES if ro in seen] + hosts + \
        [ro for ro in SHARED_ROLES + ('other',) if ro in seen]


# ----------------------------------------------------------------------------- text
def fmt(value, digits=1):
    return '-' if not _finite(value) else '%.*f' % (digits, value)


def fmt_spread(s, digits=1):
    """'min / median / max' ('-' when missing; one value when they are equal, as with one run)."""
    if s is None:
        return '-'
    if len(set(fmt(v, digits) for v in s)) == 1:
        return fmt(s[0], digits)
    return ' / '.join(fmt(v, digits) for v in s)


def runs_text(k):
    return '1 run' if k == 1 else '%d runs' % k


def fleet_cap(cores, cpu_per_drone, failing_per_core=None):
    """The fleet cap ``cores`` / ``cpu_per_drone`` [core], below ``cores`` x ``failing_per_core`` (anafi_sim.
    launch_check.fleet_cap's rule), at least 1."""
    if not cores or not cpu_per_drone:
        return None
    cap = int(cores / cpu_per_drone)
    if failing_per_core:
        cap = min(cap, int(math.ceil(cores * failing_per_core - 1e-9)) - 1)
    return max(1, cap)


def environment():
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(HERE), undefined=jinja2.StrictUndefined,
                             trim_blocks=True, lstrip_blocks=True, keep_trailing_newline=True, autoescape=False)
    env.filters['fmt'] = fmt
    env.filters['spread'] = fmt_spread
    env.filters['runs'] = runs_text
    env.filters['paragraph'] = lambda text: re.sub(r'\s+', ' ', text.strip()) + '\n'
    env.globals.update(median=lambda runs, key: median([r[key] for r in runs if _finite(r.get(key))]),
                       run_figures=run_figures, overruns=lambda run: sum(drone_values(run, 'overruns')),
                       drone_min=_min, drone_max=_max, other_jobs=other_jobs, cap_from=fleet_cap)
    return env


def context(data):
    rows = summary(data)
    machine = data.get('machine') or {}
    cores = machine.get('cores')
    loaded = sorted(set((r['layout'], r['n']) for r in data['runs']
                        if _finite(other_jobs(r, cores)) and other_jobs(r, cores) > OTHER_JOBS_LIMIT))
    cost = None
    if data.get('core_cost'):
        times, diff = data['core_cost']
        cost = {'before': times['numpy (before)'], 'after': times['plain Python (shipped)'], 'diff': diff}
    return {'data': data, 'machine': machine, 'cores': cores, 'rows': rows, 'heads': headline(data, rows),
            'roles': role_order(rows), 'hold': HOLD, 'hold_text': HOLD_TEXT, 'loaded': loaded,
            'limit': OTHER_JOBS_LIMIT, 'cost': cost, 'repeats': data.get('repeats', 1),
            'layouts': data['layouts'],
            'any_largest': any(r.get('largest_processes') for r in data['runs'])}


def markdown(data):
    """benchmarks/results/fleet.md from the results."""
    return environment().get_template('fleet.md.j2').render(**context(data))


def docs_block(data):
    """The generated block of docs/fleet.md (markers included)."""
    body = environment().get_template('fleet_docs.md.j2').render(**context(data))
    return DOCS_BEGIN + '\n' + body + DOCS_END


def replace_docs_block(text, data):
    """``text`` (docs/fleet.md) with its generated block rewritten; ValueError when the markers are missing."""
    begin, end = text.find(DOCS_BEGIN), text.find(DOCS_END)
    if begin < 0 or end < begin:
        raise ValueError('docs/fleet.md has no generated fleet-benchmark block (%s ... %s)' % (DOCS_BEGIN, DOCS_END))
    return text[:begin] + docs_block(data) + text[end + len(DOCS_END):]


def current_docs_block(text):
    """The generated block as it stands in ``text`` (None when the markers are missing)."""
    begin, end = text.find(DOCS_BEGIN), text.find(DOCS_END)
    if begin < 0 or end < begin:
        return None
    return text[begin:end + len(DOCS_END)]

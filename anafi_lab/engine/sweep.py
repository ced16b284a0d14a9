"""Sweeps of in-process runs: a YAML spec -> a grid (or list) of runs -> tidy rows of every run's metrics (pure, no
ROS; ``anafi_lab.reports.sweep_report`` runs a spec and writes the CSV, the Markdown summary and its plot).

Stage: experiments (on top of ``anafi_lab.engine.runs``; ``experiment.py sweep SPEC.yaml``). Example
specs, one per concern: anafi_lab/sweeps/.

Spec (YAML)::

    name: wind_circles                       # default: the file name
    description: free text
    scenarios: [circle_r1_v1, circle_r2_v1]  # names or paths; 'all', or a group: static, straight, circle,
                                             #   vertical (anafi_lab.reports.paper_tables)
    controllers: [mpc, pid]                  # or a mapping: controller -> {params: GRID, schedule: GRID}
    seeds: {range: [0, 20]}                  # an int, a list, or {range: [start, stop]} / {range: N}
    wind:                                    # wind cases (a list; one mapping = one case); the simulator's keys
      - {wind_x: 1.0, gust_std_horizontal: 0.5}  # wind_x, wind_y, wind_z [m/s], gust_std_horizontal,
                                             #   gust_std_vertical [m/s std], gust_time_constant [s]
    schedule: {generator_phase: [0.0, 0.05]} # GRID of engine schedule overrides (every controller)
    state_source: estimate                   # or truth: the controllers' state (ground_truth/odom)
    group_by: [wind]                         # extra columns of the summary table: wind, or a factor column
    conditions: real_flights                 # a flight-conditions profile NAME or PATH under every run (wind,
                                             #   gusts, the firmware's wind handling; anafi_sim/config/conditions)

A GRID is a mapping (nested for the PID's loops: {x_outer: {Kp: [0.5, 0.875]}}) whose list values are axes
of the grid and whose other values are fixed; the runs are every combination of scenario x controller x
wind case x params x schedule x seed. Instead of the grid keys, ``runs:`` gives an explicit list of runs
(each a mapping with scenario, controller, seed, wind, params, schedule, conditions). With ``conditions``
the summary also has the predicted e_max / e_mu / e_sigma per cell with the seed spread
(``anafi_lab.reports.conditions_report``).

Outputs in the output folder: ``runs.csv`` (tidy: one row per run; factor columns scenario, controller,
seed, the wind, ``param:<path>`` and ``schedule:<key>`` of every parameter set anywhere; metric columns:
e_mu, e_max, e_sigma [m] against the estimate, the same with ``_truth``, samples, the simulated and wall
seconds), ``summary.md`` (per scenario x controller (x ``group_by``): runs, e_mu mean, std, min, max; the
plot) and ``e_mu.png`` (the distribution of e_mu per scenario and controller over the other factors).
"""
import collections
import csv
import importlib.util
import itertools
import os

import yaml

from anafi_lab import paper
from anafi_control import registry
from anafi_lab.engine.engine import WIND_KEYS, make_schedule, simulator_config, wind_settings
from anafi_lab.engine.runs import make_task
from anafi_sim.mission.trajectory import list_scenarios
from anafi_sim.sim.conditions_profile import conditions_label, load_conditions

SPEC_KEYS = ('name', 'description', 'scenarios', 'controllers', 'seeds', 'wind', 'schedule', 'state_source',
             'group_by', 'runs', 'conditions')
RUN_KEYS = ('scenario', 'controller', 'seed', 'wind', 'params', 'schedule', 'name', 'conditions')
GROUPS = {'all': paper.ALL_SCENARIOS, 'static': paper.STATIC, 'straight': paper.STRAIGHT,
          'circle': paper.CIRCLE_SCENARIOS, 'vertical': paper.VERTICAL_SCENARIOS}
METRICS = (('e_mu', 'estimate', 'e_mu'), ('e_max', 'estimate', 'e_max'), ('e_sigma', 'estimate', 'e_sigma'),
           ('e_mu_truth', 'truth', 'e_mu'), ('e_max_truth', 'truth', 'e_max'), ('e_sigma_truth', 'truth', 'e_sigma'),
           ('e_mu_horizontal', 'estimate', 'e_mu_horizontal'), ('drift', 'estimate', 'drift'))


# ---------------------------------------------------------------------------------------------- spec
def specs_dir():
    """The folder of the shipped sweep specs: ``sweeps/`` of the anafi_lab package (package data, installed with
    it: devel and install spaces alike)."""
    for folder in importlib.util.find_spec('anafi_lab').submodule_search_locations:
        path = os.path.join(folder, 'sweeps')
        if os.path.isdir(path):
            return path
    raise RuntimeError('cannot find the sweep specs (anafi_lab/sweeps) of the anafi_lab package')


def sweep_path(name_or_path):
    """Path of a sweep spec given by name (``real_flights``: ``anafi_lab/sweeps/real_flights.yaml``) or by a
    path; a relative path that does not exist from the current folder is looked up beside the anafi_lab package
    (``anafi_lab/sweeps/x.yaml`` works from any folder). ValueError naming the known specs when none."""
    if os.path.isfile(name_or_path):
        return name_or_path
    if os.sep not in name_or_path and not name_or_path.endswith(('.yaml', '.yml')):
        path = os.path.join(specs_dir(), name_or_path + '.yaml')
    elif not os.path.isabs(name_or_path):
        path = os.path.join(os.path.dirname(os.path.dirname(specs_dir())), name_or_path)
    else:
        path = name_or_path
    if os.path.isfile(path):
        return path
    raise ValueError('no sweep spec %s (known by name: %s)' % (name_or_path, ', '.join(list_specs())))


def list_specs():
    """Names of the shipped sweep specs (anafi_lab/sweeps)."""
    folder = specs_dir()
    return sorted(os.path.splitext(f)[0] for f in os.listdir(folder) if f.endswith('.yaml'))


def load_spec(path):
    """The spec dict of a YAML file, or of a spec name (``sweep_path``; ``name`` defaults to the file name);
    ValueError when malformed."""
    path = sweep_path(path)
    with open(path) as stream:
        try:
            spec = yaml.safe_load(stream)
        except yaml.YAMLError as error:
            raise ValueError('%s: not valid YAML: %s' % (path, error))
    if not isinstance(spec, dict):
        raise ValueError('%s: a sweep spec is a mapping' % path)
    spec.setdefault('name', os.path.splitext(os.path.basename(path))[0])
    try:
        expand(spec)
    except ValueError as error:
        raise ValueError('%s: %s' % (path, error))
    return spec


def _list(value):
    return list(value) if isinstance(value, (list, tuple)) else [value]


def _scenarios(value):
    names = []
    known = set(list_scenarios())
    for item in _list(value):
        item = str(item)
        for name in GROUPS.get(item, (item,)):
            if name not in known and os.sep not in name and not name.endswith(('.yaml', '.yml')):
                raise ValueError('unknown scenario %r (known: %s)' % (name, ', '.join(sorted(known))))
            if name not in names:
                names.append(name)
    if not names:
        raise ValueError('no scenarios')
    return names


def _seeds(value):
    if value is None:
        return [None]
    if isinstance(value, dict):
        if set(value) != {'range'}:
            raise ValueError('seeds: a mapping must be {range: [start, stop]} or {range: N}, got %r' % (value,))
        r = _list(value['range'])
        if not 1 <= len(r) <= 2 or not all(isinstance(v, int) and not isinstance(v, bool) for v in r):
            raise ValueError('seeds: range needs integers, got %r' % (value['range'],))
        return list(range(*r))
    seeds = _list(value)
    for s in seeds:
        if isinstance(s, bool) or not isinstance(s, int) or s < 0:
            raise ValueError('seeds must be integers >= 0, got %r' % (s,))
    return seeds


def _flatten(grid, prefix=''):
    """[(dotted path, value)] of a nested mapping."""
    out = []
    for key, value in (grid or {}).items():
        path = '%s%s' % (prefix, key)
        if isinstance(value, dict):
            out.extend(_flatten(value, path + '.'))
        else:
            out.append((path, value))
    return out


def unflatten(pairs):
    """[(dotted path, value)] -> nested mapping ('a.b', 1) -> {'a': {'b': 1}} (the inverse of a grid's paths;
    experiment.py's KEY=VALUE options use it too)."""
    out = {}
    for path, value in pairs:
        node = out
        parts = path.split('.')
        for part in parts[:-1]:
            node = node.setdefault(part, {})
        node[parts[-1]] = value
    return out


def grid(mapping):
    """Every combination of a GRID (lists = axes): a list of nested mappings ([{}] for an empty grid)."""
    if mapping is None:
        return [{}]
    if not isinstance(mapping, dict):
        raise ValueError('a grid must be a mapping, got %r' % (mapping,))
    pairs = _flatten(mapping)
    axes = [[(path, v) for v in _list(value)] for path, value in pairs]
    for path, value in pairs:
        if isinstance(value, list) and not value:
            raise ValueError('grid axis %s is empty' % path)
    return [unflatten(combo) for combo in itertools.product(*axes)] if axes else [{}]


def _controllers(value):
    if value is None:
        value = list(paper.CONTROLLERS)
    if isinstance(value, dict):
        items = list(value.items())
    else:
        items = [(c, {}) for c in _list(value)]
    out = []
    for name, cfg in items:
        cfg = cfg or {}
        if not isinstance(cfg, dict) or set(cfg) - {'params', 'schedule'}:
            raise ValueError('controller %s: expected {params: GRID, schedule: GRID}, got %r' % (name, cfg))
        if name not in registry.names() and ':' not in str(name):
            raise ValueError('unknown controller %r (known: %s, or package.module:Class)'
                             % (name, ', '.join(registry.names())))
        out.append((str(name), grid(cfg.get('params')), grid(cfg.get('schedule'))))
    return out


def _check_schedule(overrides):
    make_schedule(overrides)
    return overrides


def expand(spec):
    """The tasks of a spec (see the module doc), each with a 'factors' entry for the tidy CSV."""
    unknown = sorted(set(spec) - set(SPEC_KEYS))
    if unknown:
        raise ValueError('unknown spec key(s) %s (known: %s)' % (', '.join(unknown), ', '.join(SPEC_KEYS)))
    state_source = spec.get('state_source', 'estimate')
    if state_source not in ('estimate', 'truth'):
        raise ValueError("state_source must be 'estimate' or 'truth', got %r" % (state_source,))
    tasks = []
    conditions = spec.get('conditions') or None
    load_conditions(conditions)
    if spec.get('runs') is not None:
        clash = sorted(k for k in ('scenarios', 'controllers', 'seeds', 'wind', 'schedule') if k in spec)
        if clash:
            raise ValueError('give either runs (a list) or the grid keys, not both (%s)' % ', '.join(clash))
        for i, run in enumerate(_list(spec['runs'])):
            if not isinstance(run, dict) or set(run) - set(RUN_KEYS) or 'scenario' not in run:
                raise ValueError('runs[%d]: a mapping with scenario and any of %s, got %r' % (i, RUN_KEYS, run))
            wind_settings(run.get('wind'))
            load_conditions(run.get('conditions'))
            _check_schedule(run.get('schedule'))
            _controllers([run.get('controller', 'mpc')])
            tasks.append(make_task(_scenarios(run['scenario'])[0], run.get('controller', 'mpc'),
                                   seed=run.get('seed'), wind=run.get('wind'), params=run.get('params'),
                                   schedule=run.get('schedule'), state_source=state_source, name=run.get('name'),
                                   detail=False, conditions=run.get('conditions', conditions)))
    else:
        winds = _list(spec.get('wind')) if spec.get('wind') is not None else [None]
        for w in winds:
            wind_settings(w)
        common = grid(spec.get('schedule'))
        seeds = _seeds(spec.get('seeds'))
        for scenario in _scenarios(spec.get('scenarios', 'all')):
            for controller, params_grid, schedule_grid in _controllers(spec.get('controllers')):
                for w in winds:
                    for params in params_grid:
                        for sched_a in common:
                            for sched_b in schedule_grid:
                                schedule = dict(sched_a)
                                schedule.update(sched_b)
                                _check_schedule(schedule)
                                for seed in seeds:
                                    tasks.append(make_task(scenario, controller, seed=seed, wind=w,
                                                           params=params or None, schedule=schedule or None,
                                                           state_source=state_source, detail=False,
                                                           conditions=conditions))
    if not tasks:
        raise ValueError('the spec gives no runs')
    for i, task in enumerate(tasks):
        task['name'] = task.get('name') or 'run%04d_%s_%s' % (i, os.path.splitext(os.path.basename(
            str(task['scenario'])))[0], str(task['controller']).split(':')[-1])
    return tasks


# ---------------------------------------------------------------------------------------------- rows
def _wind_values(wind, conditions=None):
    settings = dict(load_conditions(conditions))
    settings.update(wind_settings(wind))
    settings = simulator_config(settings)[1]
    return collections.OrderedDict((k, settings[k]) for k in WIND_KEYS)


def wind_label(wind, conditions=None):
    """'calm' or e.g. 'wind (1, 0, 0) m/s, gusts 0.5 m/s' (of the wind case over the conditions)."""
    v = _wind_values(wind, conditions)
    if not any(v[k] for k in WIND_KEYS[:5]):
        return 'calm'
    text = 'wind (%g, %g, %g) m/s' % (v['wind_x'], v['wind_y'], v['wind_z'])
    if v['gust_std_horizontal'] or v['gust_std_vertical']:
        text += ', gusts %g/%g m/s (tau %g s)' % (v['gust_std_horizontal'], v['gust_std_vertical'],
                                                 v['gust_time_constant'])
    return text


def rows(tasks, records):
    """Tidy rows (OrderedDicts, one per run) of tasks and their records; the factor columns of params and
    schedule are the union over the runs."""
    param_keys, schedule_keys = [], []
    for task in tasks:
        for path, _ in _flatten(task.get('params')):
            if path not in param_keys:
                param_keys.append(path)
        for key in (task.get('schedule') or {}):
            if key not in schedule_keys:
                schedule_keys.append(key)
    out = []
    for i, (task, rec) in enumerate(zip(tasks, records)):
        rec = rec or {}
        summary = rec.get('summary') or {}
        info = rec.get('info') or {}
        row = collections.OrderedDict([('run', i), ('name', task['name']), ('scenario', rec.get('scenario')
                                                                            or task['scenario']),
                                       ('controller', task['controller']),
                                       ('seed', info.get('seed', task.get('seed')))])
        row['conditions'] = conditions_label(task.get('conditions'))
        row.update(_wind_values(task.get('wind'), task.get('conditions')))
        params = dict(_flatten(task.get('params')))
        for path in param_keys:
            row['param:' + path] = params.get(path, '')
        schedule = task.get('schedule') or {}
        for key in schedule_keys:
            row['schedule:' + key] = schedule.get(key, '')
        row['ok'] = bool(rec.get('ok'))
        row['error'] = rec.get('error') or ''
        for column, source, key in METRICS:
            row[column] = (summary.get(source) or {}).get(key)
        row['samples'] = summary.get('samples')
        row['sim_s'] = info.get('sim_s')
        row['scenario_sim_s'] = info.get('scenario_sim_s')
        row['wall_s'] = info.get('wall_s')
        row['rtf'] = info.get('achieved_rtf')
        row['controller_cpu_s'] = info.get('controller_cpu_s')
        out.append(row)
    return out


def write_csv(table, path):
    """Write the tidy rows as CSV (None -> empty)."""
    if not table:
        raise ValueError('no rows to write')
    with open(path, 'w', newline='') as stream:
        writer = csv.writer(stream, lineterminator='\n')
        writer.writerow(list(table[0]))
        for row in table:
            writer.writerow(['' if v is None else v for v in row.values()])


def groups(tasks, table, group_by=()):
    """OrderedDict (scenario, controller, extra...) -> rows, in the order of the runs."""
    out = collections.OrderedDict()
    for task, row in zip(tasks, table):
        key = [row['scenario'], row['controller']]
        for g in group_by:
            key.append(wind_label(task.get('wind'), task.get('conditions')) if g == 'wind' else row.get(g))
        out.setdefault(tuple(key), []).append(row)
    return out

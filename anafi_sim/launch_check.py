"""Launch arguments checked before any node starts (pure: no rospy; light imports, it runs at every launch).

The launch files call ``scripts/check_launch_args.py NAME=VALUE ...`` from a ``<param command=...>``
tag, which roslaunch runs while it reads the file, before it starts the master or a node. A bad argument
makes the script print ONE line naming it (``launch argument rtf:=-1: ...``) on stderr and exit non-zero;
roslaunch then stops at once with a non-zero exit status, instead of a node dying with FATAL and being
respawned again and again (``sim.launch rtf:=-1``) or an experiment failing 90 s later without naming the
argument. ``check(args)`` holds the rules, one per argument name (``RULES``); unknown names are an error
of the launch file itself.
"""
import math
import os
import re

from anafi_sim.numeric import parse_integer, parse_number, range_problem

_BASE_NAME = re.compile(r'^[A-Za-z][A-Za-z0-9_]*$')
_FILE_NAME = re.compile(r'^[A-Za-z0-9_.-]+$')


def _number(value):
    return parse_number(value)     # the nodes' parser (anafi_sim/ros/params.py)


def positive(value):
    x = _number(value)
    if x is None or x <= 0.0:
        return 'must be a finite number > 0'
    return None


def non_negative(value):
    x = _number(value)
    if x is None or x < 0.0:
        return 'must be a finite number >= 0'
    return None


def optional_number(value):
    if value.strip() == '':
        return None
    return None if _number(value) is not None else 'must be a finite number or empty'


def flag(value):
    return None if value in ('true', 'false', 'True', 'False', '1', '0') else 'must be true or false'


def _natural(value):
    n = parse_integer(value)
    return n if n is not None and n >= 0 and value.strip()[:1] != '-' else None


def port(value):
    if _natural(value) is None or not 0 <= _natural(value) <= 65535:
        return 'must be an integer port in 0..65535 (0: any free port)'
    return None


def base_name(value):
    return None if _BASE_NAME.match(value) else 'must be a ROS base name (a letter, then letters, digits, _)'


def _config_dir(*parts):
    from anafi_sim import paths
    return paths.config_path(*parts)


def model_file(value):
    """A model YAML in anafi_sim/config (a file name) or an absolute path inside the folders the simulator
    reads a model from (the package's config, the root-owned /etc/anafi_sim/data_folders), that exists."""
    from anafi_sim import trusted
    path = value if os.path.isabs(value) else _config_dir(value)
    if os.path.isabs(value) and os.path.isfile(path):
        try:
            trusted.file_parameter(value, trusted.allowed_folders([_config_dir()]), 'model_file')
        except ValueError as error:
            return str(error).split(': ', 1)[-1]
    if not (os.path.isabs(value) or _FILE_NAME.match(value)) or not os.path.isfile(path):
        known = sorted(f for f in os.listdir(_config_dir()) if f.startswith('anafi_model') and f.endswith('.yaml'))
        return 'no model file %s (known: %s)' % (path, ', '.join(known))
    return None


def scenario(value):
    """A scenario name of anafi_sim/config/scenarios (a file name without .yaml)."""
    folder = _config_dir('scenarios')
    if _FILE_NAME.match(value) and os.path.isfile(os.path.join(folder, value + '.yaml')):
        return None
    known = sorted(f[:-5] for f in os.listdir(folder) if f.endswith('.yaml'))
    return 'no such scenario (known: %s; or scenario_file:=PATH)' % ', '.join(known)


def scenario_file(value):
    if value == '' or os.path.isfile(os.path.expanduser(value)):
        return None
    return 'no such file'


#: [cores] CPU of one drone of a fleet at real time, per fleet layout (per_drone: a process per role and drone;
#: shared: fleet_host.py processes hosting one role of every drone): simulator + telemetry CLI + interface + mirror
#: at 100 Hz + MPC + generator and the drone's share of the world and the master, the median over the runs at the
#: largest fleet holding real time in benchmarks/results/fleet.json (benchmarks/bench_fleet.py; the generated
#: block of docs/fleet.md quotes it; test/unit/sim/test_fleet_figures.py checks they agree).
CPU_PER_DRONE = {'per_drone': 0.206, 'shared': 0.063}
#: [drones per core] the smallest fleet measured NOT to hold real time above the largest one holding, per core of
#: the measuring machine, per layout (None: no larger size failed), from the same runs: the cap stays below it
#: (where the latency of a busy process limits before the cores are full, cores / CPU_PER_DRONE overshoots)
FAILING_PER_CORE = {'per_drone': 4.0, 'shared': 15.0}
#: the layout fleet.launch starts by default
DEFAULT_LAYOUT = 'per_drone'


def available_cores():
    """CPU cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def fleet_cap(cores=None, layout=DEFAULT_LAYOUT):
    """The largest fleet this machine runs at real time in ``layout``: cores / CPU_PER_DRONE[layout], and below
    cores x FAILING_PER_CORE[layout] (the smallest size measured not to hold, scaled to the cores), at least 1
    (KeyError for an unknown layout)."""
    cores = available_cores() if cores is None else cores
    cap = int(cores / CPU_PER_DRONE[layout])
    failing = FAILING_PER_CORE[layout]
    if failing:
        cap = min(cap, int(math.ceil(cores * failing - 1e-9)) - 1)
    return max(1, cap)


def fleet_size_problem(count, max_drones=0, cores=None, layout=DEFAULT_LAYOUT):
    """None when ``count`` drones fit (``max_drones`` > 0: the user's own cap instead of ``fleet_cap``), else
    what is wrong (names the cap, where it comes from and how to override it)."""
    if max_drones and max_drones > 0:
        cap, why = int(max_drones), 'max_drones:=%d' % max_drones
    else:
        n = available_cores() if cores is None else cores
        cap = fleet_cap(n, layout)
        where = 'benchmarks/results/fleet.md' if layout == DEFAULT_LAYOUT else \
            '%s layout, benchmarks/results/fleet.md' % layout
        bound = '' if cap == int(n / CPU_PER_DRONE[layout]) or cap == 1 else \
            ', below %d drones (%g per core) measured not to hold' % (cap + 1, FAILING_PER_CORE[layout])
        why = ('%d cores / %.3f core per drone%s (%s): slower than real time beyond it; max_drones:=N to raise it'
               % (n, CPU_PER_DRONE[layout], bound, where))
    if count > cap:
        return '%d drones is more than the fleet cap of %d (%s)' % (count, cap, why)
    return None


def drones(value):
    if _natural(value) is None:
        return 'must be an integer >= 0 (0: the fleet file\'s list)'
    return None


def max_drones(value):
    return None if _natural(value) is not None else 'must be an integer >= 0 (0: the cap derived from the CPU cores)'


def layout(value):
    return None if value in ('',) + tuple(sorted(CPU_PER_DRONE)) else \
        'must be %s, or empty (the fleet file\'s)' % ' or '.join(sorted(CPU_PER_DRONE))


def controller(value):
    return None if value in ('mpc', 'pid', 'preview_mpc') else 'must be mpc, pid or preview_mpc'


def pid_mode(value):
    return None if value in ('distributed', 'single') else 'must be distributed or single'


#: argument name -> rule (value text -> None when good, else what is wrong)
RULES = {
    'rtf': positive, 'use_sim_time': flag, 'telemetry_port': port, 'drone_name': base_name,
    'initial_x': optional_number, 'initial_y': optional_number, 'initial_yaw': optional_number,
    'model_file': model_file, 'scenario': scenario, 'scenario_file': scenario_file, 'controller': controller,
    'pid_mode': pid_mode, 'mirror': flag, 'record': flag, 'plot': flag, 'rviz': flag, 'sync': flag,
    'sync_period': positive, 'sync_timeout': positive, 'progress_period': non_negative,
    'ready_timeout': positive, 'mirror_rate': positive, 'drones': drones, 'max_drones': max_drones,
    'layout': layout,
}


def check(args, context_rules=None):
    """``args``: (name, value text) pairs; ``context_rules``: {name: rule(value, {name: value})}, rules that
    read the other arguments too (the script adds the fleet file's: ``anafi_sim.mission.fleet.launch_problem``).
    Returns the error lines (empty when every argument is good);
    ValueError for an argument name without a rule (a mistake in the launch file). A scenario is not
    checked when a scenario_file is given (the file wins)."""
    errors = []
    given = dict(args)
    for name, value in args:
        context_rules = context_rules or {}
        rule = RULES.get(name) or context_rules.get(name)
        if rule is None:
            raise ValueError('check_launch_args.py: no rule for the argument %r (known: %s)'
                             % (name, ', '.join(sorted(RULES))))
        if name == 'scenario' and given.get('scenario_file'):
            continue
        problem = rule(value, given) if name in context_rules else rule(value)
        if problem is None and name not in context_rules and _number(value) is not None:
            problem = range_problem(name, _number(value))
        if problem is None and name == 'drones' and int(value) > 0:
            limit = given.get('max_drones', '0')
            layout = given.get('layout') or DEFAULT_LAYOUT     # '' = the fleet file's: its launcher checks again
            problem = fleet_size_problem(int(value), _natural(limit) or 0,
                                         layout=layout if layout in CPU_PER_DRONE else DEFAULT_LAYOUT)
        if problem:
            errors.append('launch argument %s:=%s: %s' % (name, value, problem))
    return errors


def parse(argv):
    """['name=value', ...] -> [(name, value)]; ValueError for a word without '='."""
    out = []
    for word in argv:
        name, sep, value = word.partition('=')
        if not sep or not name:
            raise ValueError('check_launch_args.py: expected NAME=VALUE, got %r' % (word,))
        out.append((name, value))
    return out

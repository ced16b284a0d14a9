"""Launch arguments checked before any node starts (pure: no rospy; light imports, it runs at every launch).

The launch files call ``scripts/check_launch_args.py NAME=VALUE ...`` from a ``<param command=...>``
tag, which roslaunch runs while it reads the file, before it starts the master or a node. A bad argument
makes the script print ONE line naming it (``launch argument rtf:=-1: ...``) on stderr and exit non-zero;
roslaunch then stops at once with a non-zero exit status, instead of a node dying with FATAL and being
respawned again and again (``sim.launch rtf:=-1``) or an experiment failing 90 s later without naming the
argument. ``check(args)`` holds the rules, one per argument name (``RULES``); unknown names are an error
of the launch file itself.

roslaunch ignores a command-line argument the launch file does not declare (``contoller:=pid`` would fly the
default controller). The script also reads the command line of roslaunch (its parent) and refuses such an
argument with one line naming it and the nearest declared one (``unknown_arguments``), when the launch file
that runs the check is the one the user started (the arguments reach only that file, not the files it includes).
"""
import collections
import difflib
import math
import os
import re

from anafi_control import registry
from anafi_sim.numeric import parse_integer, parse_number, range_problem
from anafi_sim.run_files import FIGURE_FORMATS
from anafi_sim.untrusted import LOG_CHARS, clip

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


def finite(value):
    return None if _number(value) is not None else 'must be a finite number'


def optional_positive(value):
    return None if value.strip() == '' else positive(value)


def state_source(value):
    return None if value in ('state_enu', 'pose_speed') else 'must be state_enu or pose_speed'


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


#: the values of scenario_file that name no file (experiment.launch's default: none)
NO_SCENARIO_FILE = ('', 'none')


def scenario_file(value):
    if value in NO_SCENARIO_FILE or os.path.isfile(os.path.expanduser(value)):
        return None
    return 'no such file'


#: [cores] CPU of one drone of a fleet at real time, per fleet layout (per_drone: a process per role and drone;
#: shared: fleet_host.py processes hosting one role of every drone): simulator + telemetry CLI + interface + mirror
#: at 100 Hz + MPC + generator and the drone's share of the world and the master, the median over the runs at the
#: largest fleet holding real time in benchmarks/results/fleet.json (benchmarks/bench_fleet.py; the generated
#: block of docs/fleet.md quotes it; test/unit/sim/test_fleet_figures.py checks they agree). Figures of the
#: machine that measured them (REFERENCE_MACHINE): another machine's cap comes from its own measurement
#: (``machine_cap``), these only scale its conservative default.
CPU_PER_DRONE = {'per_drone': 0.206, 'shared': 0.063}
#: [drones per core] the smallest fleet measured NOT to hold real time above the largest one holding, per core of
#: the measuring machine, per layout (None: no larger size failed), from the same runs: the cap stays below it
#: (where the latency of a busy process limits before the cores are full, cores / CPU_PER_DRONE overshoots)
FAILING_PER_CORE = {'per_drone': 4.0, 'shared': 15.0}
#: the machine benchmarks/results/fleet.json measured CPU_PER_DRONE and FAILING_PER_CORE on (its 'machine')
REFERENCE_MACHINE = {'cpu_model': 'AMD EPYC', 'cores': 2, 'date': '2026-11-27 05:55'}
#: the conservative default cap of a machine that has not measured its own: the reference machine's cap for
#: these cores times this (another CPU may be slower: on a 2-core Intel Xeon the shared layout held 16 drones
#: where the reference held 20 and its cap said 29)
DEFAULT_CAP_SCALE = 0.5
#: the cache of this machine's own cap figures, under the ROS home ($ROS_HOME, else ~/.ros): one entry per CPU
#: model and core count, written by CALIBRATE_COMMAND
CAP_CACHE = ('anafi_sim', 'fleet_cap.yaml')
CALIBRATE_COMMAND = 'python benchmarks/bench_fleet.py --calibrate-cap'
#: the layout fleet.launch starts by default
DEFAULT_LAYOUT = 'per_drone'

#: [cores] the most CPU one host process of the shared layout (fleet_host.py) may take at real time, on the machine
#: it runs on: one interpreter runs one thread at a time, and a host near a whole core falls behind (its simulators'
#: loop, its 100 Hz ground truth) before the cores are full. The shared layout splits its hosts by drone so that
#: each stays within it (``drones_per_host``).
HOST_CORE_BUDGET = 0.5
#: [cores] CPU per drone of each host split by drone, on the reference machine (benchmarks/results/fleet.json,
#: shared layout, 20 drones: fleet_drones_1 + fleet_drones_2 1.5 + 1.6 % of a core per drone, fleet_ground_truth
#: 2.7 %)
REFERENCE_HOST_CPU_PER_DRONE = {'fleet_drones': 0.031, 'fleet_ground_truth': 0.027}

CapFigures = collections.namedtuple('CapFigures', 'cpu_per_drone failing_per_core cpu_model cores date source')
CapFigures.__doc__ = ('The figures a fleet cap comes from: cpu_per_drone {layout: core per drone}, failing_per_core '
                      '{layout: drones per core or None}, the machine that measured them (cpu_model, cores, date) '
                      'and where they were read (source: a path, or the reference\'s results page).')
Cap = collections.namedtuple('Cap', 'drones cores layout figures measured why')
Cap.__doc__ = ('A fleet cap: drones (the largest fleet), cores, layout, figures (CapFigures), measured (True: '
               'this machine\'s own measurement; False: the conservative default), why (the text naming the '
               'figure and where it came from, for the refusal line).')

REFERENCE = CapFigures(CPU_PER_DRONE, FAILING_PER_CORE, REFERENCE_MACHINE['cpu_model'], REFERENCE_MACHINE['cores'],
                       REFERENCE_MACHINE['date'], 'benchmarks/results/fleet.md')


def available_cores():
    """CPU cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def cpu_model(cpuinfo='/proc/cpuinfo'):
    """This machine's CPU model name: the first 'model name' of ``cpuinfo``, else what platform knows (as
    anafi_sim.processes.cpu_model, which the benchmark pages name; test_launch_check checks they agree)."""
    try:
        with open(cpuinfo) as f:
            for line in f:
                if line.startswith('model name'):
                    return line.split(':', 1)[1].strip()
    except (IOError, OSError):
        pass
    import platform
    return platform.processor() or 'unknown'


def ros_home(environ=None):
    """The ROS home folder: $ROS_HOME, else ~/.ros."""
    environ = os.environ if environ is None else environ
    return environ.get('ROS_HOME') or os.path.join(os.path.expanduser('~'), '.ros')


def cap_cache_path(environ=None):
    """Where this machine's cap figures are cached: <ROS home>/anafi_sim/fleet_cap.yaml."""
    return os.path.join(ros_home(environ), *CAP_CACHE)


def machine_key(model, cores):
    """The cache's key of a machine: its CPU model and core count."""
    return '%s, %d cores' % (model, int(cores))


def fleet_cap(cores=None, layout=DEFAULT_LAYOUT, figures=REFERENCE):
    """The largest fleet of ``figures`` (default the reference machine's) at real time in ``layout`` on ``cores``:
    cores / cpu_per_drone[layout], and below cores x failing_per_core[layout] (the smallest size measured not to
    hold, scaled to the cores), at least 1 (KeyError for an unknown layout)."""
    cores = available_cores() if cores is None else cores
    cap = int(cores / figures.cpu_per_drone[layout])
    failing = figures.failing_per_core.get(layout)
    if failing:
        cap = min(cap, int(math.ceil(cores * failing - 1e-9)) - 1)
    return max(1, cap)


def default_cap(cores, layout=DEFAULT_LAYOUT):
    """The conservative cap of a machine that has not measured its own: DEFAULT_CAP_SCALE x the reference's cap
    for ``cores``, at least 1."""
    return max(1, int(DEFAULT_CAP_SCALE * fleet_cap(cores, layout)))


def _number_or_none(value, positive=True):
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or \
            (positive and value <= 0):
        raise ValueError('not a finite number > 0: %r' % (value,))
    return float(value)


def parse_cap_entry(entry, source):
    """One machine's entry of the cache -> CapFigures; ValueError naming what is wrong. Entry: {cpu_model, cores,
    date, layouts: {layout: {cpu_per_drone: core, failing_per_core: drones per core or null, ...}}}."""
    if not isinstance(entry, dict) or not isinstance(entry.get('layouts'), dict):
        raise ValueError('an entry must be a mapping with layouts: {layout: {cpu_per_drone, ...}}')
    cpu, failing = {}, {}
    for layout, figs in entry['layouts'].items():
        if layout not in CPU_PER_DRONE or not isinstance(figs, dict):
            raise ValueError('layouts: unknown layout or not a mapping: %r' % (layout,))
        cpu[layout] = _number_or_none(figs.get('cpu_per_drone'))
        if cpu[layout] is None:
            raise ValueError('layouts.%s: no cpu_per_drone' % layout)
        failing[layout] = _number_or_none(figs.get('failing_per_core'))
    return CapFigures(cpu, failing, str(entry.get('cpu_model', '')), entry.get('cores'), str(entry.get('date', '?')),
                      source)


def read_cap_cache(path, model, cores):
    """This machine's cap figures (CapFigures) from the cache at ``path`` for CPU ``model`` and ``cores``; None
    when the file or the machine's entry is missing, or the file or entry is unreadable (the default applies)."""
    import yaml
    try:
        with open(path) as f:
            data = yaml.safe_load(f)
        entry = (data or {}).get('machines', {}).get(machine_key(model, cores))
        return None if entry is None else parse_cap_entry(entry, path)
    except Exception:     # a missing, cut or malformed cache never stops a launch: the default applies
        return None


def cap_cache_with(data, model, cores, date, layouts, **extra):
    """The cache's document ``data`` (None: a new one) with the entry of (``model``, ``cores``) replaced by one
    measured at ``date`` (text): ``layouts`` {layout: {cpu_per_drone, failing_per_core, ...}}, merged over the
    layouts it had before; ``extra``: more facts of the measurement. ValueError for a figure that is not one."""
    data = dict(data) if isinstance(data, dict) else {}
    machines = dict(data.get('machines') or {}) if isinstance(data.get('machines'), dict) else {}
    key = machine_key(model, cores)
    old = machines.get(key) if isinstance(machines.get(key), dict) else {}
    merged = dict(old.get('layouts') or {}) if isinstance(old.get('layouts'), dict) else {}
    merged.update(layouts)
    entry = dict(extra, cpu_model=model, cores=int(cores), date=date, layouts=merged)
    parse_cap_entry(entry, 'new entry')
    machines[key] = entry
    data['machines'] = machines
    data.setdefault('about', 'fleet caps measured on this machine (%s); anafi_sim.launch_check reads them'
                    % CALIBRATE_COMMAND)
    return data


def machine_cap(layout=DEFAULT_LAYOUT, cores=None, model=None, cache_path=None):
    """The fleet cap of this machine (Cap): from its own figures in the cache (``cache_path``, default
    cap_cache_path()) for its CPU ``model`` and ``cores`` when they hold ``layout``, else the conservative
    default (``default_cap``). ``why`` names the figure and where it came from."""
    cores = available_cores() if cores is None else cores
    model = cpu_model() if model is None else model
    path = cap_cache_path() if cache_path is None else cache_path
    figures = read_cap_cache(path, model, cores)
    if figures is not None and layout in figures.cpu_per_drone:
        cap = fleet_cap(cores, layout, figures)
        why = 'measured here on %s, %d cores at %s: %s (%s)' % (
            model, int(cores), figures.date, _cap_reason(cap, cores, layout, figures), path)
        return Cap(cap, cores, layout, figures, True, why)
    cap = default_cap(cores, layout)
    reference = fleet_cap(cores, layout)
    where = 'benchmarks/results/fleet.md' if layout == DEFAULT_LAYOUT else \
        '%s layout, benchmarks/results/fleet.md' % layout
    why = ('conservative default, not measured on this machine (%s, %d cores): %g x the %d of the reference '
           'machine (%s, %d cores at %s: %s, %s)' % (
               model, int(cores), DEFAULT_CAP_SCALE, reference, REFERENCE_MACHINE['cpu_model'],
               REFERENCE_MACHINE['cores'], REFERENCE_MACHINE['date'], _cap_reason(reference, cores, layout, REFERENCE),
               where))
    return Cap(cap, cores, layout, REFERENCE, False, why)


def drones_per_host(host_cpu_per_drone, budget=HOST_CORE_BUDGET):
    """{host: the most drones whose CPU (``host_cpu_per_drone`` {host: core per drone}) fits in ``budget`` cores,
    at least 1}."""
    return dict((host, max(1, int(budget / cost + 1e-9))) for host, cost in host_cpu_per_drone.items())


def _host_costs(entry):
    """{host: core per drone} of a cache entry's shared layout (``host_cpu_per_drone``, as --calibrate-cap
    measures it), None when it has none or one is not a number > 0."""
    try:
        figs = entry['layouts']['shared']['host_cpu_per_drone']
        costs = dict((host, _number_or_none(figs[host])) for host in REFERENCE_HOST_CPU_PER_DRONE)
    except (KeyError, TypeError, ValueError):
        return None
    return None if None in costs.values() else costs


def host_costs(cores=None, model=None, cache_path=None):
    """(host_cpu_per_drone {host: core per drone}, why) of this machine, the figures the shared layout's split
    comes from: the hosts' own cost measured here (the cache's ``host_cpu_per_drone``); else the reference
    machine's host costs scaled by this machine's measured cost of a drone in the shared layout over the
    reference's (``cpu_per_drone``); else, unmeasured, the reference's divided by DEFAULT_CAP_SCALE."""
    cores = available_cores() if cores is None else cores
    model = cpu_model() if model is None else model
    path = cap_cache_path() if cache_path is None else cache_path
    entry = None
    try:
        import yaml
        with open(path) as f:
            entry = ((yaml.safe_load(f) or {}).get('machines') or {}).get(machine_key(model, cores))
    except Exception:     # a missing or malformed cache: the default applies
        entry = None
    measured = _host_costs(entry) if isinstance(entry, dict) else None
    if measured is not None:
        return measured, 'the hosts\' CPU per drone measured here (%s)' % path
    figures = None
    if isinstance(entry, dict):
        try:
            figures = parse_cap_entry(entry, path)
        except ValueError:
            figures = None
    if figures is not None and 'shared' in figures.cpu_per_drone:
        scale = figures.cpu_per_drone['shared'] / CPU_PER_DRONE['shared']
        return (dict((h, c * scale) for h, c in REFERENCE_HOST_CPU_PER_DRONE.items()),
                'the reference\'s host costs x %.2f, this machine\'s CPU per drone (%.3f, measured here: %s) over '
                'the reference\'s (%.3f)' % (scale, figures.cpu_per_drone['shared'], path, CPU_PER_DRONE['shared']))
    return (dict((h, c / DEFAULT_CAP_SCALE) for h, c in REFERENCE_HOST_CPU_PER_DRONE.items()),
            'conservative default, not measured on this machine: the reference\'s host costs / %g' % DEFAULT_CAP_SCALE)


def machine_drones_per_host(cores=None, model=None, cache_path=None):
    """({host: drones}, why): the shared layout's split on this machine, each host within HOST_CORE_BUDGET
    (``drones_per_host`` of ``host_costs``)."""
    costs, why = host_costs(cores, model, cache_path)
    limits = drones_per_host(costs)
    return limits, '%s per host (%s; %g core each at most): %s' % (
        ' / '.join('%d drones for %s' % (limits[h], h) for h in sorted(limits)),
        ', '.join('%s %.3f core per drone' % (h, costs[h]) for h in sorted(costs)), HOST_CORE_BUDGET, why)


def _cap_reason(cap, cores, layout, figures):
    failing = figures.failing_per_core.get(layout)
    bound = '' if cap == int(cores / figures.cpu_per_drone[layout]) or cap == 1 or not failing else \
        ', below %d drones (%g per core) measured not to hold' % (cap + 1, failing)
    return '%g cores / %.3f core per drone%s' % (cores, figures.cpu_per_drone[layout], bound)


def fleet_size_problem(count, max_drones=0, cores=None, layout=DEFAULT_LAYOUT, cap=None):
    """None when ``count`` drones fit (``max_drones`` > 0: the user's own cap instead of the machine's), else
    what is wrong (names the cap, the figure it comes from and where, and how to override it). ``cap``: the
    machine's Cap (default ``machine_cap(layout, cores)``)."""
    if max_drones and max_drones > 0:
        limit, why = int(max_drones), 'max_drones:=%d' % max_drones
    else:
        cap = machine_cap(layout, cores) if cap is None else cap
        limit = cap.drones
        why = '%s: slower than real time beyond it; %smax_drones:=N to raise it' % (
            cap.why, '' if cap.measured else 'measure this machine\'s cap: %s; or ' % CALIBRATE_COMMAND)
    if count > limit:
        return '%d drones is more than the fleet cap of %d (%s)' % (count, limit, why)
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
    """experiment.launch's controller:=, one of anafi_control.registry's (``experiment_names``)."""
    known = registry.experiment_names()
    return None if value in known else 'must be %s or %s' % (', '.join(known[:-1]), known[-1])


def plot_format(value):
    return None if value in FIGURE_FORMATS else 'must be %s' % ' or '.join(FIGURE_FORMATS)


def pid_mode(value):
    return None if value in ('distributed', 'single') else 'must be distributed or single'


#: argument name -> rule (value text -> None when good, else what is wrong)
RULES = {
    'rtf': positive, 'use_sim_time': flag, 'telemetry_port': port, 'drone_name': base_name,
    'initial_x': optional_number, 'initial_y': optional_number, 'initial_yaw': optional_number,
    'model_file': model_file, 'scenario': scenario, 'scenario_file': scenario_file, 'controller': controller,
    'pid_mode': pid_mode, 'mirror': flag, 'record': flag, 'plot': flag, 'plot_format': plot_format,
    'plot_dpi': positive, 'rviz': flag, 'sync': flag,
    'sync_period': positive, 'sync_timeout': positive, 'progress_period': non_negative,
    'ready_timeout': positive, 'mirror_rate': positive, 'drones': drones, 'max_drones': max_drones,
    'layout': layout,
    'fence_radius': positive, 'fence_min_altitude': finite, 'fence_max_altitude': finite,
    'max_reach': optional_positive, 'bridge_only': flag, 'source': state_source, 'world_yaw': finite,
}


def check(args, context_rules=None, cap_cache=None):
    """``args``: (name, value text) pairs; ``context_rules``: {name: rule(value, {name: value})}, rules that
    read the other arguments too (the script adds the fleet file's: ``anafi_sim.mission.fleet.launch_problem``);
    ``cap_cache``: the fleet cap's cache file (default cap_cache_path()).
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
        if name == 'scenario' and given.get('scenario_file', '') not in NO_SCENARIO_FILE:
            continue
        problem = rule(value, given) if name in context_rules else rule(value)
        if problem is None and name not in context_rules and _number(value) is not None:
            problem = range_problem(name, _number(value))
        if problem is None and name == 'drones' and int(value) > 0:
            limit = given.get('max_drones', '0')
            layout = given.get('layout') or DEFAULT_LAYOUT     # '' = the fleet file's: its launcher checks again
            layout = layout if layout in CPU_PER_DRONE else DEFAULT_LAYOUT
            problem = fleet_size_problem(int(value), _natural(limit) or 0, layout=layout,
                                         cap=machine_cap(layout, cache_path=cap_cache))
        if problem:
            errors.append('launch argument %s:=%s: %s' % (name, _shown(value), problem))
    low, high = _number(given.get('fence_min_altitude', '')), _number(given.get('fence_max_altitude', ''))
    if low is not None and high is not None and not low < high:
        errors.append('launch argument fence_max_altitude:=%s: must be above fence_min_altitude:=%s'
                      % (given['fence_max_altitude'], given['fence_min_altitude']))
    return errors


def _shown(value):
    """The argument's text for a one-line message: as typed when printable and short, else clipped (a repr)."""
    return value if value.isprintable() and len(value) <= LOG_CHARS else clip(value)


#: the programs whose command line is roslaunch's: the roslaunch script, run by a python interpreter or directly
_PYTHON = re.compile(r'^python[0-9.]*$')


def roslaunch_argv(cmdline):
    """The arguments of a roslaunch command line (``cmdline``: a process's argv, e.g. from /proc/PID/cmdline),
    or None when it is not ``roslaunch ARGS`` or ``pythonX /path/roslaunch ARGS`` (a test runner, a program
    using roslaunch's API: their arguments are not a user's launch arguments)."""
    words = list(cmdline)
    if words and os.path.basename(words[0]) == 'roslaunch':
        return words[1:]
    if len(words) >= 2 and _PYTHON.match(os.path.basename(words[0])) and os.path.basename(words[1]) == 'roslaunch':
        return words[2:]
    return None


def command_line_arguments(argv):
    """The launch arguments of roslaunch's ``argv`` as roslaunch reads them (rosgraph.names.load_mappings):
    [(name, value)] of the words NAME:=VALUE with both sides non-empty (spaces stripped), without private
    parameters (_name:=) and special keys (__name:=, __ns:=, ...)."""
    out = []
    for word in argv:
        parts = word.split(':=')
        if len(parts) != 2:
            continue
        name, value = parts[0].strip(), parts[1].strip()
        if name and value and not name.startswith('_'):
            out.append((name, value))
    return out


def declared_arguments(launch_xml):
    """The argument names a launch file (its XML text) declares: every <arg name=...> but those inside an
    <include> (the arguments it passes to the included file). ValueError when the text is not a launch file."""
    import xml.etree.ElementTree as ElementTree
    try:
        root = ElementTree.fromstring(launch_xml)
    except ElementTree.ParseError as error:
        raise ValueError('not a launch file: %s' % error)
    names = []

    def walk(element):
        for child in element:
            if child.tag == 'arg' and child.get('name'):
                names.append(child.get('name'))
            elif child.tag != 'include':
                walk(child)
    walk(root)
    return names


def unknown_arguments(given, declared, launch_name):
    """One line per argument of ``given`` ([(name, value)]) that ``declared`` (names) does not hold, naming it
    and the nearest declared name (difflib), else how to list them."""
    errors = []
    for name, value in given:
        if name in declared:
            continue
        near = difflib.get_close_matches(name, sorted(set(declared)), n=1, cutoff=0.6)
        hint = 'did you mean %s?' % near[0] if near else \
            'its arguments: roslaunch anafi_sim %s --ros-args' % launch_name
        errors.append('launch argument %s:=%s: not an argument of %s (%s)'
                      % (_shown(name), _shown(value), launch_name, hint))
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

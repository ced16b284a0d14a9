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

_BASE_NAME = re.compile(r'^[A-Za-z][A-Za-z0-9_]*$')
_FILE_NAME = re.compile(r'^[A-Za-z0-9_.-]+$')


def _number(value):
    try:
        out = float(value)
    except ValueError:
        return None
    return out if math.isfinite(out) else None


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


def port(value):
    if not value.isdigit() or not 0 <= int(value) <= 65535:
        return 'must be an integer port in 0..65535 (0: any free port)'
    return None


def base_name(value):
    return None if _BASE_NAME.match(value) else 'must be a ROS base name (a letter, then letters, digits, _)'


def _config_dir(*parts):
    from anafi_sim import paths
    return paths.config_path(*parts)


def model_file(value):
    """A model YAML in anafi_sim/config (a file name) or an absolute path, that exists."""
    path = value if os.path.isabs(value) else _config_dir(value)
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
    'ready_timeout': positive, 'mirror_rate': positive, 'drones': positive,
}


def check(args):
    """``args``: (name, value text) pairs. Returns the error lines (empty when every argument is good);
    ValueError for an argument name without a rule (a mistake in the launch file). A scenario is not
    checked when a scenario_file is given (the file wins)."""
    errors = []
    given = dict(args)
    for name, value in args:
        rule = RULES.get(name)
        if rule is None:
            raise ValueError('check_launch_args.py: no rule for the argument %r (known: %s)'
                             % (name, ', '.join(sorted(RULES))))
        if name == 'scenario' and given.get('scenario_file'):
            continue
        problem = rule(value)
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

"""Flight-conditions profiles: named sets of simulator settings (wind, gusts, the firmware's wind handling).

Stage: simulated drone. A profile is a YAML file of ``anafi_sim.sim.drone_model.DEFAULT_SETTINGS`` keys (the
sim.yaml keys of the model), e.g. ``anafi_sim/config/conditions/real_flights.yaml`` (the paper's outdoor
flights, written by ``anafi_lab/cli/calibrate_conditions.py``). It is loaded over sim.yaml: by the
in-process engine (``Engine(conditions=...)``, ``experiment.py --conditions``, a sweep spec's
``conditions:``) and by the launch files (``conditions:=NAME`` loads the file into the simulator node's
private namespace). No profile: sim.yaml as it is (no wind).

A profile is named by NAME (``[A-Za-z0-9_]+``: ``anafi_sim/config/conditions/NAME.yaml``, found through the
package) or given by a path to a ``.yaml`` file.
"""
import collections
import os
import re

from anafi_sim import paths
from anafi_sim.sim.drone_model import DEFAULT_SETTINGS, validate_settings

NAME = re.compile(r'^[A-Za-z0-9_]+$')
# keys a profile may hold: the model's simulator settings except where the drone starts
PROFILE_KEYS = tuple(k for k in DEFAULT_SETTINGS if not k.startswith('initial_'))


def conditions_dir():
    """The package's conditions folder (anafi_sim/config/conditions)."""
    return paths.config_path('conditions')


def list_conditions():
    """Names of the package's profiles (sorted)."""
    directory = conditions_dir()
    if not os.path.isdir(directory):
        return []
    return sorted(f[:-5] for f in os.listdir(directory) if f.endswith('.yaml') and NAME.match(f[:-5]))


def profile_path(name_or_path, folders=None):
    """The file of a profile NAME or PATH (with ``folders``, a PATH only inside one of them: a parameter);
    ValueError when there is none."""
    text = str(name_or_path)
    if NAME.match(text):
        path = os.path.join(conditions_dir(), text + '.yaml')
        if not os.path.isfile(path):
            raise ValueError('unknown conditions %r (known: %s)' % (text, ', '.join(list_conditions()) or 'none'))
        return path
    if not text.endswith('.yaml') or not os.path.isfile(text):
        raise ValueError('conditions must be a NAME (%s) or the path of a .yaml file, got %r'
                         % (', '.join(list_conditions()) or 'none', text[:200]))
    if folders is not None:
        from anafi_sim import trusted
        return trusted.file_parameter(text, folders, 'conditions', suffixes=('.yaml',))
    return text


def parameter_folders():
    """The folders a ``~conditions`` parameter (anyone may set it) may name a profile in: the package's config,
    $ROS_HOME, the temp folder (where the lab writes its profiles) and the root-owned /etc/anafi_sim/data_folders."""
    import tempfile
    from anafi_sim import trusted
    return trusted.allowed_folders([paths.config_path()], [trusted.ros_home(), tempfile.gettempdir()])


def load_conditions(name_or_path, folders=None):
    """{setting: value} of a profile (NAME or PATH; None or '' -> {}); ValueError on an unreadable file, an
    unknown key or a bad value."""
    if name_or_path in (None, ''):
        return collections.OrderedDict()
    from anafi_sim.safe_yaml import load_yaml
    path = profile_path(name_or_path, folders)
    data = load_yaml(path, what='the conditions %s' % path)
    if not isinstance(data, dict):
        raise ValueError('%s: a conditions profile is a mapping of simulator settings' % path)
    unknown = sorted(str(k) for k in data if k not in PROFILE_KEYS)
    if unknown:
        raise ValueError('%s: unknown key(s) %s (known: %s)' % (path, ', '.join(unknown), ', '.join(PROFILE_KEYS)))
    try:
        validate_settings(data)
    except ValueError as error:
        raise ValueError('%s: %s' % (path, error))
    return collections.OrderedDict((k, float(data[k])) for k in PROFILE_KEYS if k in data)


def conditions_label(name_or_path):
    """A short label: the profile's name ('none' without one)."""
    if name_or_path in (None, ''):
        return 'none'
    text = str(name_or_path)
    return text if NAME.match(text) else os.path.splitext(os.path.basename(text))[0]


def wind_text(settings):
    """One line describing the wind of simulator ``settings`` (a profile's or sim.yaml's), '' without wind:
    e.g. 'wind 5.3 m/s toward (-0.60, -0.80) ENU, gusts 1.5 m/s, firmware wind handling K 0.98'."""
    import math
    wx, wy = float(settings.get('wind_x', 0.0)), float(settings.get('wind_y', 0.0))
    gust = float(settings.get('gust_std_horizontal', 0.0))
    speed = math.hypot(wx, wy)
    if speed == 0.0 and gust == 0.0:
        return ''
    parts = ['wind %.1f m/s' % speed + (' toward (%.2f, %.2f) ENU' % (wx / speed, wy / speed) if speed else '')]
    if gust:
        parts.append('gusts %.1f m/s' % gust)
    if float(settings.get('wind_compensation', 0.0)) > 0.0:
        parts.append('firmware wind handling K %.2f' % float(settings['wind_compensation']))
    return ', '.join(parts)

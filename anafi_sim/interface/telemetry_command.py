"""The telemetry command the interface may run: one of the allowed tools, every argument checked (pure, no ROS).

Stage: telemetry -> **interface** (what the interface starts to read the telemetry).

The interface's ``~telemetry_command`` (and a fleet file's ``telemetry_command``) is never handed to a
shell and never runs an arbitrary program. The tools it may run are a set of full paths (``allowed_tools``):

- Sphinx's ``tlm-data-logger`` at its install locations (``SPHINX_TOOL_PATHS``);
- the package's stand-in ``tlm_data_logger.py`` and its copy under Sphinx's name ``tlm-data-logger`` (the
  devel / install space executables and the source scripts, found through the package: ``stand_in_paths``);
- the full paths listed in the root-owned site settings file ``/etc/anafi_sim/telemetry_tools``
  (``anafi_sim.trusted``; read only when it is owned by root and writable by nobody else).

A path of the set is kept only when it is safe (``anafi_sim.trusted.unsafe_reason``: the file and every
folder above it owned by root or the node's user, writable by nobody else) and, when it is a symbolic link,
only when it points to another path of the set. The command's program is either a bare name
(``tlm-data-logger``: Sphinx's, at the first allowed path outside the package; ``tlm_data_logger.py``: the
package's stand-in) or a path whose
resolved target is in the set; the argument list returned holds the resolved path, so nothing found on PATH
or swapped in later runs. A file name alone never admits a program: ``/anywhere/tlm-data-logger`` is refused.

The program is followed by the arguments of these tools and nothing else: ``[-r MS] inet:HOST:PORT`` (MS a
finite number >= 0, HOST a host name or IPv4 address, PORT an integer in 0..65535). The command is a string
(split like a shell would split words, no shell features: quotes only) or a list of arguments; the result is
the list passed to ``subprocess.Popen`` as is. Anything else raises ``ValueError`` naming what was refused, so
a parameter set by anyone who can reach the ROS master cannot run code on the drone's host.
"""
import math
import os
import re
import shlex

from anafi_sim import trusted

#: Sphinx's telemetry tool (file name)
SPHINX_TOOL = 'tlm-data-logger'
#: where Parrot's Sphinx packages install it
SPHINX_TOOL_PATHS = ('/opt/parrot-sphinx/usr/bin/tlm-data-logger', '/usr/bin/tlm-data-logger')
#: our stand-in (file name of anafi_sim/scripts/tlm_data_logger.py)
STAND_IN = 'tlm_data_logger.py'
KNOWN_TOOLS = (SPHINX_TOOL, STAND_IN)

_HOST = re.compile(r'^[A-Za-z0-9](?:[A-Za-z0-9.-]{0,252})$')


def stand_in_paths(names=KNOWN_TOOLS):
    """Real paths of the package's own telemetry tools (the stand-in ``tlm_data_logger.py`` and its copy under
    Sphinx's name ``tlm-data-logger`` for the reference nodes): the devel / install space executables (first: what
    the bare name runs, as ``$(find anafi_sim)/anafi_sim/scripts/tlm_data_logger.py`` does in a launch file),
    the source scripts."""
    found = []
    for name in names:
        try:
            from catkin.find_in_workspaces import find_in_workspaces
            found += find_in_workspaces(search_dirs=['libexec'], project='anafi_sim', path=name)
        except Exception:   # catkin not importable (plain pytest without ROS)
            pass
        try:
            from anafi_sim import paths
            found.append(paths.data_path('scripts', name))
        except Exception:   # no package found: only the workspace executables above
            pass
    return [os.path.realpath(p) for p in found if os.path.isfile(p)]


def allowed_tools(stand_ins=None, sphinx_paths=SPHINX_TOOL_PATHS, settings_dir=None, owners=None):
    """(allowed, refused, own): the resolved paths of the tools that may run (Sphinx's, the settings file's,
    the package's own), {listed path: why it is not allowed} for the listed ones that exist but are unsafe,
    and the package's own tools (never what the bare name ``tlm-data-logger`` runs: that is Sphinx's)."""
    if stand_ins is None:
        stand_ins = stand_in_paths()
    listed = [os.path.normpath(p) for p in list(sphinx_paths)
              + trusted.settings_list(trusted.TELEMETRY_TOOLS, directory=settings_dir) + list(stand_ins)]
    allowed, refused = [], {}
    for path in listed:
        if not os.path.lexists(path):
            continue
        real = os.path.realpath(path)
        if real != path and real not in listed:
            refused[path] = 'a symbolic link to %s, which is not an allowed tool' % real
            continue
        reason = trusted.unsafe_reason(real, owners)
        if reason is None and not os.access(real, os.X_OK):
            reason = '%s is not executable' % real
        if reason is not None:
            refused[path] = reason
        elif real not in allowed:
            allowed.append(real)
    return allowed, refused, [os.path.realpath(p) for p in stand_ins]


def _words(command):
    if isinstance(command, str):
        try:
            words = shlex.split(command)
        except ValueError as error:
            raise ValueError('telemetry_command %r: %s' % (command[:200], error))
    elif isinstance(command, (list, tuple)):
        words = []
        for word in command:
            if isinstance(word, bool) or not isinstance(word, (str, int, float)):
                raise ValueError('telemetry_command: every argument must be a string or a number, got %r'
                                 % (repr(word)[:200],))
            words.append(str(word))
    else:
        raise ValueError('telemetry_command must be a string or a list of arguments, got %r' % (repr(command)[:200],))
    if not words:
        raise ValueError('telemetry_command is empty')
    return words


def _executable(word, tools, resolve_names):
    """argv[0] for the tool named or pointed to by ``word``; ValueError when it is not an allowed tool."""
    allowed, refused, own = tools
    if word in KNOWN_TOOLS:
        if not resolve_names:
            return word
        for path in allowed:
            if os.path.basename(path) == word and (word == STAND_IN) == (path in own):
                return path
        why = ''.join('; %s refused: %s' % item for item in sorted(refused.items()))
        raise ValueError('telemetry_command: %s is not installed at an allowed path (%s)%s'
                         % (word, ', '.join(SPHINX_TOOL_PATHS) if word == SPHINX_TOOL else 'the package\'s stand-in',
                            why))
    if os.path.isabs(word):
        normal = os.path.normpath(word)
        if normal in refused:
            raise ValueError('telemetry_command: refused to run %r: %s' % (word[:200], refused[normal]))
        real = os.path.realpath(word)
        if real in allowed:
            return real
        raise ValueError('telemetry_command: refused to run %r: not one of the allowed tools (%s; more in %s)'
                         % (word[:200], ', '.join(allowed) or 'none installed',
                            os.path.join(trusted.SETTINGS_DIR, trusted.TELEMETRY_TOOLS)))
    raise ValueError('telemetry_command: refused to run %r: the telemetry command must be one of the known tools '
                     '(%s, or a full path listed as allowed), with the arguments [-r MS] inet:HOST:PORT'
                     % (word[:200], ' or '.join(KNOWN_TOOLS)))


def _rate(text):
    try:
        value = float(text)
    except ValueError:
        value = float('nan')
    if not (math.isfinite(value) and value >= 0.0):
        raise ValueError('telemetry_command: -r takes a number of milliseconds >= 0, got %r' % (text[:200],))
    return text


def _endpoint(text):
    parts = text.split(':')
    if len(parts) != 3 or parts[0] != 'inet' or not _HOST.match(parts[1]) or not parts[2].isdigit() \
            or not 0 <= int(parts[2]) <= 65535:
        raise ValueError('telemetry_command: the endpoint must be inet:HOST:PORT (HOST a name or an IPv4 '
                         'address, PORT in 0..65535: 0 = the port the interface learns from ~simulator_node), '
                         'got %r' % (text[:200],))
    return text


def allowed_argv(command, tools=None, resolve_names=True):
    """The argument list to run for ``command`` (a string or a list); ValueError when it is not allowed.

    tools: ``allowed_tools()`` (default: computed now); resolve_names False keeps a bare tool name as is
    (a fleet file checked on a host that may not run the tool itself)."""
    words = _words(command)
    argv = [_executable(words[0], allowed_tools() if tools is None else tools, resolve_names)]
    rest = words[1:]
    if len(rest) >= 2 and rest[0] == '-r':
        argv += ['-r', _rate(rest[1])]
        rest = rest[2:]
    if len(rest) != 1:
        raise ValueError('telemetry_command: %s takes [-r MS] inet:HOST:PORT, got the arguments %r'
                         % (os.path.basename(argv[0]), repr(words[1:])[:200]))
    argv.append(_endpoint(rest[0]))
    return argv

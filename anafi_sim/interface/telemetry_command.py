"""The telemetry command the interface may run: one of the known tools, every argument checked (pure, no ROS).

Stage: telemetry -> **interface** (what the interface starts to read the telemetry).

The interface's ``~telemetry_command`` (and a fleet file's ``telemetry_command``) is never handed to a
shell and never runs an arbitrary program: ``allowed_argv`` accepts exactly

- ``tlm-data-logger`` -- Sphinx's own tool, by name (found on PATH when started) or by an absolute path
  whose file name is ``tlm-data-logger``;
- ``tlm_data_logger.py`` -- our stand-in, by name or by the path of the package's own script (the source
  script, or the ``lib/anafi_sim`` executable of a devel / install space: ``stand_in_paths``),

followed by the arguments of these tools and nothing else: ``[-r MS] inet:HOST:PORT`` (MS a finite number
>= 0, HOST a host name or IPv4 address, PORT an integer in 1..65535). The command is a string (split
like a shell would split words, no shell features: quotes only) or a list of arguments; the result is
the list passed to ``subprocess.Popen`` as is. Anything else raises ``ValueError`` naming what was
refused, so a parameter set by anyone who can reach the ROS master cannot run code on the drone's host.
"""
import math
import os
import re
import shlex

#: Sphinx's telemetry tool (file name)
SPHINX_TOOL = 'tlm-data-logger'
#: our stand-in (file name of anafi_sim/scripts/tlm_data_logger.py)
STAND_IN = 'tlm_data_logger.py'
KNOWN_TOOLS = (SPHINX_TOOL, STAND_IN)

_HOST = re.compile(r'^[A-Za-z0-9](?:[A-Za-z0-9.-]{0,252})$')


def stand_in_paths():
    """Real paths of the package's stand-in: the devel / install space executables (first: what the bare name
    runs, as ``$(find anafi_sim)/anafi_sim/scripts/tlm_data_logger.py`` does in a launch file), the source script."""
    found = []
    try:
        from catkin.find_in_workspaces import find_in_workspaces
        found += find_in_workspaces(search_dirs=['libexec'], project='anafi_sim', path=STAND_IN)
    except Exception:   # catkin not importable (plain pytest without ROS)
        pass
    try:
        from anafi_sim import paths
        found.append(paths.data_path('scripts', STAND_IN))
    except Exception:   # no package found: only the workspace executables above
        pass
    return [os.path.realpath(p) for p in found if os.path.isfile(p)]


def _words(command):
    if isinstance(command, str):
        try:
            words = shlex.split(command)
        except ValueError as error:
            raise ValueError('telemetry_command %r: %s' % (command, error))
    elif isinstance(command, (list, tuple)):
        words = []
        for word in command:
            if isinstance(word, bool) or not isinstance(word, (str, int, float)):
                raise ValueError('telemetry_command: every argument must be a string or a number, got %r' % (word,))
            words.append(str(word))
    else:
        raise ValueError('telemetry_command must be a string or a list of arguments, got %r' % (command,))
    if not words:
        raise ValueError('telemetry_command is empty')
    return words


def _executable(word, stand_ins):
    """argv[0] for the tool named or pointed to by ``word``; ValueError when it is none of the known tools."""
    known = ' or '.join(KNOWN_TOOLS)
    if word == SPHINX_TOOL:
        return word                        # Popen looks it up on PATH
    if os.path.isabs(word) and os.path.basename(word) == SPHINX_TOOL:
        return word
    if word == STAND_IN or (os.path.isabs(word) and os.path.basename(word) == STAND_IN):
        if stand_ins is None:
            stand_ins = stand_in_paths()
        if not stand_ins:
            raise ValueError('telemetry_command: the stand-in %s of the anafi_sim package is not found' % STAND_IN)
        if word == STAND_IN:
            return stand_ins[0]
        if os.path.realpath(word) in stand_ins:
            return word
        raise ValueError('telemetry_command: %r is not the package\'s stand-in (%s)' % (word, ', '.join(stand_ins)))
    raise ValueError('telemetry_command: refused to run %r: the telemetry command must be one of the known tools '
                     '(%s), with the arguments [-r MS] inet:HOST:PORT' % (word, known))


def _rate(text):
    try:
        value = float(text)
    except ValueError:
        value = float('nan')
    if not (math.isfinite(value) and value >= 0.0):
        raise ValueError('telemetry_command: -r takes a number of milliseconds >= 0, got %r' % (text,))
    return text


def _endpoint(text):
    parts = text.split(':')
    if len(parts) != 3 or parts[0] != 'inet' or not _HOST.match(parts[1]) or not parts[2].isdigit() \
            or not 0 <= int(parts[2]) <= 65535:
        raise ValueError('telemetry_command: the endpoint must be inet:HOST:PORT (HOST a name or an IPv4 '
                         'address, PORT in 0..65535: 0 = the port the interface learns from ~simulator_node), '
                         'got %r' % (text,))
    return text


def allowed_argv(command, stand_ins=None):
    """The argument list to run for ``command`` (a string or a list); ValueError when it is not allowed.

    stand_ins: real paths of the package's stand-in (default ``stand_in_paths()``)."""
    words = _words(command)
    argv = [_executable(words[0], stand_ins)]
    rest = words[1:]
    if len(rest) >= 2 and rest[0] == '-r':
        argv += ['-r', _rate(rest[1])]
        rest = rest[2:]
    if len(rest) != 1:
        raise ValueError('telemetry_command: %s takes [-r MS] inet:HOST:PORT, got the arguments %r'
                         % (os.path.basename(argv[0]), words[1:]))
    argv.append(_endpoint(rest[0]))
    return argv

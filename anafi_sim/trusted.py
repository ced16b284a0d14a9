"""Which files the stack may run or read when a parameter names them (pure Python, no ROS).

A ROS 1 parameter can be set by anyone who reaches the master, so a path in a parameter is never trusted by
itself. A path is *safe* when the file and every folder above it are owned by a trusted user (root or the
user running the node) and writable by nobody else: no group- or world-writable file or folder, except a
root-owned folder with the sticky bit (``/tmp``), where nobody can rename or replace an entry they do not
own. Symbolic links are resolved first; a link is as good as what it points to.

Site settings (folders and tools beyond the package's own) come from files in ``SETTINGS_DIR``
(``/etc/anafi_sim``), read only when the file itself is safe and owned by root: one absolute path per line,
``#`` starts a comment (the cores take the folder as an argument, so tests use their own). The environment
variable ``ANAFI_SIM_SETTINGS_DIR`` (set by whoever starts the process, never by a ROS parameter) names another
folder, whose files may then be owned by root or the user running the node (a test's own settings).
"""
import os
import stat

#: the folder of the site settings files (root-owned)
SETTINGS_DIR = '/etc/anafi_sim'
#: extra telemetry tools (full paths), one a line
TELEMETRY_TOOLS = 'telemetry_tools'
#: extra folders from which file parameters may be read, one a line
DATA_FOLDERS = 'data_folders'


def default_owners():
    """Users trusted to own a file the stack runs or reads: root and the user running it."""
    return (0, os.getuid())


def unsafe_reason(path, owners=None):
    """None when ``path`` (resolved) and every folder above it are safe (see the module); else why not."""
    owners = default_owners() if owners is None else tuple(owners)
    real = os.path.realpath(path)
    current = real
    while True:
        try:
            st = os.stat(current)
        except OSError as error:
            return '%s: %s' % (current, error.strerror or error)
        mode = st.st_mode
        sticky_root = stat.S_ISDIR(mode) and mode & stat.S_ISVTX and st.st_uid == 0
        if st.st_uid not in owners:
            return '%s is owned by uid %d (trusted: %s)' % (current, st.st_uid, ', '.join(map(str, owners)))
        if mode & (stat.S_IWGRP | stat.S_IWOTH) and not (current != real and sticky_root):
            return '%s is group- or world-writable' % current
        parent = os.path.dirname(current)
        if parent == current:
            return None
        current = parent


#: the environment variable that names another settings folder
SETTINGS_ENV = 'ANAFI_SIM_SETTINGS_DIR'


def settings_list(name, owners=None, directory=None):
    """The absolute paths listed in the settings file ``name`` of ``directory`` (default: $ANAFI_SIM_SETTINGS_DIR,
    else /etc/anafi_sim) (empty when it is missing or not safe). ``owners`` (default root, and the running user
    for a folder other than /etc/anafi_sim): who may own the file."""
    directory = directory or os.environ.get(SETTINGS_ENV) or SETTINGS_DIR
    if owners is None:
        owners = (0,) if directory == SETTINGS_DIR else default_owners()
    path = os.path.join(directory, name)
    if not os.path.isfile(path) or unsafe_reason(path, owners) is not None:
        return []
    out = []
    try:
        with open(path) as f:
            text = f.read(65536)
    except (OSError, UnicodeDecodeError):
        return []
    for line in text.splitlines():
        line = line.split('#', 1)[0].strip()
        if line and os.path.isabs(line):
            out.append(os.path.normpath(line))
    return out


def within(path, folders):
    """True when the resolved ``path`` lies inside one of the (resolved) ``folders``."""
    real = os.path.realpath(path)
    for folder in folders:
        top = os.path.realpath(folder)
        if real == top or real.startswith(top.rstrip(os.sep) + os.sep):
            return True
    return False


def ros_home():
    """Where ROS and the stack write their runs (``$ROS_HOME``, default ``~/.ros``)."""
    return os.environ.get('ROS_HOME') or os.path.join(os.path.expanduser('~'), '.ros')


def allowed_folders(package_folders, extra=(), directory=None):
    """The folders a file parameter may name: ``package_folders`` (the package's config folders), ``extra``
    (folders the stack itself writes to, given by the caller, never by a parameter) and the folders listed in
    the root-owned settings file ``/etc/anafi_sim/data_folders``."""
    return [f for f in list(package_folders) + list(extra) + settings_list(DATA_FOLDERS, directory=directory) if f]


def file_parameter(value, folders, what, suffixes=('.yaml', '.yml')):
    """The real path of the file a parameter names: ``value`` a name relative to ``folders[0]`` or an absolute
    path, accepted only when it is a regular file with one of ``suffixes`` inside one of ``folders`` (real paths
    compared: no ``..`` or link leads out). ValueError names the parameter and the folders, never the file's
    content."""
    if not isinstance(value, str) or not value or '\x00' in value:
        raise ValueError('%s must name a file, got %r' % (what, repr(value)[:100]))
    if not folders:
        raise ValueError('%s: no folder to read files from' % what)
    path = os.path.realpath(value if os.path.isabs(value) else os.path.join(folders[0], value))
    shown = value if len(value) <= 200 else value[:200] + '...'
    if not path.endswith(tuple(suffixes)) or not within(path, folders):
        raise ValueError('%s: refused %r: only %s files in %s (more folders: %s)'
                         % (what, shown, '/'.join(suffixes), ', '.join(folders),
                            os.path.join(SETTINGS_DIR, DATA_FOLDERS)))
    if not os.path.isfile(path):
        raise ValueError('%s: no file %r' % (what, shown))
    return path

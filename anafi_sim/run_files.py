"""A run's result files: one new folder per run, written atomically, failures marked; the one YAML reader and
writer of the package (pure, no ROS).

- ``new_run_dir(out_dir, name)``: a folder ``out_dir/<name>-<YYYYmmdd-HHMMSS>-<pid>`` that did not exist
  (created exclusively, so two runs started in the same second never share one), and the link
  ``out_dir/latest`` pointing at it (replaced atomically).
- ``atomic_write(path, write)``: ``write(stream)`` fills ``<path>.tmp-<pid>`` in the same folder, which is
  flushed, synced and renamed to ``path`` only when complete; on any error (a full disk: ENOSPC) the
  temporary file is removed and the error raised, so ``path`` is either the complete new file or absent.
- ``atomic_path(path)``: the same for writers that take a path (a CSV writer, matplotlib).
- ``read_yaml(path, default)`` / ``write_yaml(path, data)``: a YAML file read (``default`` when missing; with
  ``tolerant`` also when cut or malformed) and written atomically, block style, keys in their order.
- ``failed_name(path)``: ``RUN.csv`` -> ``RUN.FAILED.csv``: the name of a file of a run that did not end
  with a valid measurement; ``mark_failed(paths)`` renames the ones that exist.
- ``remove_previous(paths)``: a rerun into the same names first removes the previous run's files, so a
  killed rerun can never leave them next to its own partial files.
- ``FIGURE_FORMATS``, ``FIGURE_DPI``: the formats a run's figure is written in (its file's extension), its dpi.
"""
import contextlib
import os
import time

import yaml

FIGURE_FORMATS = ('png', 'svg', 'pdf')
"""A run's figure: PNG (the default), SVG or PDF (anafi_sim.mission.plots.save; launch argument plot_format)."""
FIGURE_DPI = 80
"""Dots per inch of a run's figure by default (small PNGs; launch argument plot_dpi, range numeric.PARAMETER_RANGES)."""

LATEST = 'latest'


def new_run_dir(out_dir, name, now=None, pid=None):
    """Create and return a new folder for a run in ``out_dir``; ``out_dir/latest`` links to it."""
    out_dir = os.path.abspath(os.path.expanduser(out_dir))
    os.makedirs(out_dir, exist_ok=True)
    stamp = time.strftime('%Y%m%d-%H%M%S', time.localtime(time.time() if now is None else now))
    base = '%s-%s-%d' % (name, stamp, os.getpid() if pid is None else pid)
    for i in range(1000):
        path = os.path.join(out_dir, base if i == 0 else '%s-%d' % (base, i))
        try:
            os.mkdir(path)
        except FileExistsError:
            continue
        update_latest(out_dir, path)
        return path
    raise OSError('cannot create a new run folder %s-* in %s' % (base, out_dir))


def update_latest(out_dir, run_dir):
    """Point ``out_dir/latest`` at ``run_dir`` (relative link, replaced atomically); OSError is ignored
    where links are impossible (the run folder is the result, the link a convenience)."""
    link = os.path.join(out_dir, LATEST)
    tmp = '%s.tmp-%d' % (link, os.getpid())
    try:
        if os.path.lexists(tmp):
            os.remove(tmp)
        os.symlink(os.path.relpath(run_dir, out_dir), tmp)
        os.replace(tmp, link)
    except OSError:
        try:
            os.remove(tmp)
        except OSError:
            pass


def atomic_write(path, write, mode='w'):
    """Write ``path`` through ``write(stream)`` into a temporary file renamed when complete (see module doc)."""
    directory = os.path.dirname(os.path.abspath(path))
    os.makedirs(directory, exist_ok=True)
    tmp = '%s.tmp-%d' % (path, os.getpid())
    try:
        with open(tmp, mode, **({} if 'b' in mode else {'newline': ''})) as stream:
            write(stream)
            stream.flush()
            os.fsync(stream.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.remove(tmp)
        except OSError:
            pass
        raise


@contextlib.contextmanager
def atomic_path(path, suffix=''):
    """For writers that take a path: yields a temporary path (ending with ``suffix``, e.g. '.png' for a
    writer that picks the format by extension) that is synced and renamed to ``path`` when the block ends
    without error, and removed otherwise."""
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    tmp = '%s.tmp-%d%s' % (path, os.getpid(), suffix)
    try:
        yield tmp
        with open(tmp, 'rb') as stream:
            os.fsync(stream.fileno())
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


def atomic_write_text(path, text):
    """``atomic_write`` of a string."""
    atomic_write(path, lambda stream: stream.write(text))


def read_yaml(path, default=None, tolerant=False):
    """The YAML document at ``path``; ``default`` when the file is missing or empty. A malformed or unreadable
    file raises, or with ``tolerant`` (a run's result file, which may be cut) gives ``default`` too."""
    if not os.path.isfile(path):
        return default
    try:
        with open(path) as stream:
            data = yaml.safe_load(stream)
    except (OSError, yaml.YAMLError):
        if not tolerant:
            raise
        return default
    return default if data is None else data


def write_yaml(path, data):
    """``data`` as block-style YAML (keys in their order), written atomically."""
    atomic_write_text(path, yaml.safe_dump(data, default_flow_style=False, sort_keys=False))


def failed_name(path):
    """``dir/RUN.csv`` -> ``dir/RUN.FAILED.csv`` (``RUN.run.yaml`` -> ``RUN.FAILED.run.yaml``)."""
    directory, name = os.path.split(path)
    if not name:
        raise ValueError('no file name in %r' % (path,))
    head, dot, tail = name.partition('.')
    if '.FAILED' in name:
        return path
    return os.path.join(directory, head + '.FAILED' + dot + tail if dot else name + '.FAILED')


def mark_failed(paths, state=None, reason=None):
    """Rename every existing file of ``paths`` to its ``failed_name``; returns the new names. With ``state``, a
    YAML mapping among them that has a ``state`` says it inside too: its state becomes ``state`` (and
    ``reason``, when given, is added), written atomically under the FAILED name."""
    out = []
    for path in paths:
        if path and os.path.exists(path):
            target = failed_name(path)
            data = None
            if state is not None and path.endswith(('.yaml', '.yml')):
                try:
                    data = read_yaml(path, tolerant=True)
                except (OSError, ValueError):
                    data = None
            if isinstance(data, dict) and 'state' in data:
                data['state'] = state
                if reason:
                    data.setdefault('reason', reason)
                write_yaml(target, data)
                os.remove(path)
            else:
                os.replace(path, target)
            out.append(target)
    return out


def remove_previous(paths):
    """Remove the files of ``paths`` (and their FAILED names) left by a previous run; returns the removed."""
    removed = []
    for path in paths:
        for candidate in (path, failed_name(path)) if path else ():
            if os.path.lexists(candidate):
                os.remove(candidate)
                removed.append(candidate)
    return removed

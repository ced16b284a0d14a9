"""The anafi_control name clash: the paper authors' ROS message package and this project's control library.

With theirs first on the path our nodes stop with one clear message (no traceback), except from our devel space
(its relay puts our source tree first); with ours first both work (our package extends its path, so their
``anafi_control.msg`` is found behind it).
"""
import ast
import glob
import os
import subprocess
import sys

import pytest
from conftest import ROOT

SCRIPTS = sorted(glob.glob(os.path.join(ROOT, 'anafi_sim', 'scripts', '*.py')))


@pytest.fixture
def their_package(tmp_path):
    """A message-only package named anafi_control as catkin generates it (empty __init__.py, msg/)."""
    package = tmp_path / 'theirs' / 'anafi_control'
    (package / 'msg').mkdir(parents=True)
    (package / '__init__.py').write_text('')
    (package / 'msg' / '__init__.py').write_text('THEIRS = True\n')
    return str(tmp_path / 'theirs')


def run(args, path, cwd):
    """``python args`` with PYTHONPATH = ``path`` (the source tree, as an install space lays it out: no
    devel-space relay) then the current PYTHONPATH's entries without an anafi_control (ROS's own) in ``cwd``."""
    ros = [p for p in os.environ.get('PYTHONPATH', '').split(os.pathsep)
           if p and not os.path.isdir(os.path.join(p, 'anafi_control'))]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(list(path) + ros))
    return subprocess.run([sys.executable] + args, env=env, cwd=cwd, stdout=subprocess.PIPE,
                          stderr=subprocess.PIPE, universal_newlines=True, timeout=60)


def test_theirs_first_stops_a_node_with_a_clear_message(their_package, tmp_path):
    node = os.path.join(ROOT, 'anafi_sim', 'scripts', 'controller_node.py')
    result = run([node], [their_package, ROOT], str(tmp_path))
    assert result.returncode == 1
    assert 'Traceback' not in result.stderr and 'ImportError' not in result.stderr
    assert "'anafi_control' found first on the path (%s" % os.path.join(their_package, 'anafi_control') \
        in result.stderr
    assert "The anafi_control name clash" in result.stderr


def test_ours_first_finds_both(their_package, tmp_path):
    code = ('import anafi_sim, anafi_control.contract, anafi_control.msg as m; '
            'assert m.THEIRS; print(anafi_control.contract.__file__)')
    result = run(['-c', code], [ROOT, their_package], str(tmp_path))
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip().startswith(os.path.join(ROOT, 'anafi_control'))


DEVEL_PYTHON = os.path.join(ROOT, '.ws', 'devel', 'lib', 'python3', 'dist-packages')


@pytest.mark.skipif(not os.path.isfile(os.path.join(DEVEL_PYTHON, 'anafi_sim', '__init__.py')),
                    reason='no devel space: run make setup')
def test_theirs_first_works_in_our_devel_space(their_package, tmp_path):
    """The devel space's anafi_sim/__init__.py (catkin's relay) puts our source tree first on sys.path when it is
    imported: theirs first on PYTHONPATH, our nodes still find our anafi_control, theirs behind it."""
    code = ('import anafi_sim, anafi_control.contract, anafi_control.msg as m; '
            'assert m.THEIRS; print(anafi_control.contract.__file__)')
    result = run(['-c', code], [their_package, DEVEL_PYTHON], str(tmp_path))
    assert result.returncode == 0, result.stderr
    assert os.path.realpath(result.stdout.strip()).startswith(os.path.join(os.path.realpath(ROOT), 'anafi_control'))


def _top_level_imports(path):
    with open(path) as f:
        tree = ast.parse(f.read(), filename=path)
    for node in tree.body:
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name.split('.')[0]
        elif isinstance(node, ast.ImportFrom) and node.module:
            yield node.module.split('.')[0]


@pytest.mark.parametrize('script', SCRIPTS, ids=os.path.basename)
def test_every_script_imports_anafi_sim_before_anafi_control(script):
    roots = [name for name in _top_level_imports(script) if name in ('anafi_sim', 'anafi_control')]
    assert not roots or roots[0] == 'anafi_sim', \
        '%s imports anafi_control before anafi_sim (whose import checks the name clash)' % script

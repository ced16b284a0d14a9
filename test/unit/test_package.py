"""Package-level checks: catkin_lint, pure cores, node scripts, Python 3.8 syntax."""
import ast
import glob
import os
import shutil
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
CORE_MODULES = sorted(glob.glob(os.path.join(ROOT, 'anafi_sim', '*.py')) +
                      glob.glob(os.path.join(ROOT, 'anafi_control', '*.py')))
SCRIPTS = sorted(glob.glob(os.path.join(ROOT, 'anafi_sim', 'scripts', '*.py')))
ALL_PY = sorted(set(CORE_MODULES + SCRIPTS + glob.glob(os.path.join(ROOT, '**', '*.py'), recursive=True)))
ALL_PY = [p for p in ALL_PY if '/.venv/' not in p and '/.ws/' not in p]


def _imports(path):
    tree = ast.parse(open(path).read(), filename=path)
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(a.name.split('.')[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module.split('.')[0])
    return names


@pytest.mark.skipif(shutil.which('catkin_lint') is None, reason='catkin_lint not installed')
def test_catkin_lint_reports_no_errors():
    out = subprocess.run(['catkin_lint', ROOT], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                         universal_newlines=True)
    errors = [line for line in out.stdout.splitlines() if ': error:' in line]
    assert not errors, out.stdout


@pytest.mark.parametrize('path', CORE_MODULES, ids=[os.path.relpath(p, ROOT) for p in CORE_MODULES])
def test_core_modules_do_not_import_rospy(path):
    assert 'rospy' not in _imports(path), 'pure core module imports rospy: ' + path


@pytest.mark.parametrize('path', SCRIPTS, ids=[os.path.relpath(p, ROOT) for p in SCRIPTS])
def test_scripts_are_executable_python3(path):
    with open(path) as f:
        assert f.readline().strip() == '#!/usr/bin/env python3'
    assert os.access(path, os.X_OK)


@pytest.mark.parametrize('path', ALL_PY, ids=[os.path.relpath(p, ROOT) for p in ALL_PY])
def test_parses_as_python_3_8(path):
    ast.parse(open(path).read(), filename=path, feature_version=(3, 8))

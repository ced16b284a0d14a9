"""Package-level checks: catkin_lint, pure cores, node scripts, Python 3.8 syntax."""
import ast
import glob
import os
import shutil
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def _stage(path):
    """The stage a module belongs to: 'anafi_control', 'anafi_sim.<subpackage>', 'anafi_sim.paths', ..."""
    parts = os.path.relpath(path, ROOT)[:-3].split(os.sep)
    if parts[0] == 'anafi_control':
        return 'anafi_control'
    return 'anafi_sim' if parts[1] == '__init__' else 'anafi_sim.' + parts[1]


#: pure cores: every module of anafi_sim (recursively) but the nodes (scripts/) and the ROS glue (ros/),
#: and the control library
CORE_MODULES = sorted(p for p in glob.glob(os.path.join(ROOT, 'anafi_sim', '**', '*.py'), recursive=True) +
                      glob.glob(os.path.join(ROOT, 'anafi_control', '**', '*.py'), recursive=True)
                      if _stage(p) not in ('anafi_sim.scripts', 'anafi_sim.ros'))
SCRIPTS = sorted(glob.glob(os.path.join(ROOT, 'anafi_sim', 'scripts', '*.py')))
ALL_PY = sorted(set(CORE_MODULES + SCRIPTS + glob.glob(os.path.join(ROOT, '**', '*.py'), recursive=True)))
ALL_PY = [p for p in ALL_PY if '/.venv/' not in p and '/.ws/' not in p]

_SIM, _TLM, _IF, _GZ, _EXP, _CAL, _CTL, _PATHS = (
    'anafi_sim.sim', 'anafi_sim.telemetry', 'anafi_sim.interface', 'anafi_sim.gazebo', 'anafi_sim.experiments',
    'anafi_sim.calibration', 'anafi_control', 'anafi_sim.paths')
#: the one direction of the data flow: what each stage may import (besides itself). Simulated drone ->
#: telemetry -> interface -> gazebo mirror | controllers; experiments and calibration beside, on top;
#: ros/ (node glue) and scripts/ (nodes) above all cores; anafi_control stands alone.
ALLOWED_IMPORTS = {
    'anafi_sim': set(),
    _CTL: set(),
    _PATHS: set(),
    'anafi_sim.harness': set(),
    'anafi_sim.launch_check': {_PATHS},
    _TLM: {_PATHS},
    _SIM: {_TLM, _CTL, _PATHS},
    _IF: {_TLM, _CTL, _PATHS},
    _GZ: {_IF, _TLM, _CTL, _PATHS},
    _EXP: {_SIM, _TLM, _IF, _GZ, _CTL, _PATHS},
    _CAL: {_EXP, _SIM, _TLM, _CTL, _PATHS},
}


def _imports(path, full=False):
    """Top-level names (or, with ``full``, dotted module names, 'from anafi_sim import x' as anafi_sim.x)."""
    tree = ast.parse(open(path).read(), filename=path)
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(a.name if full else a.name.split('.')[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module if full else node.module.split('.')[0])
            if full and node.module == 'anafi_sim':
                names.update('anafi_sim.' + a.name for a in node.names)
    return names


def _import_stage(module):
    parts = module.split('.')
    if parts[0] == 'anafi_control':
        return _CTL
    if parts[0] == 'anafi_sim' and len(parts) > 1:
        return 'anafi_sim.' + parts[1]
    return None


@pytest.mark.skipif(shutil.which('catkin_lint') is None, reason='catkin_lint not installed')
def test_catkin_lint_reports_no_errors():
    out = subprocess.run(['catkin_lint', ROOT], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                         universal_newlines=True)
    errors = [line for line in out.stdout.splitlines() if ': error:' in line]
    assert not errors, out.stdout


@pytest.mark.parametrize('path', CORE_MODULES, ids=[os.path.relpath(p, ROOT) for p in CORE_MODULES])
def test_core_modules_do_not_import_rospy(path):
    assert 'rospy' not in _imports(path), 'pure core module imports rospy: ' + path


@pytest.mark.parametrize('path', CORE_MODULES, ids=[os.path.relpath(p, ROOT) for p in CORE_MODULES])
def test_core_imports_point_one_way(path):
    stage = _stage(path)
    allowed = ALLOWED_IMPORTS.get(stage)
    assert allowed is not None, 'module outside the known stages (add it to ALLOWED_IMPORTS): %s' % path
    wrong = sorted(m for m in _imports(path, full=True)
                   if _import_stage(m) not in (None, stage) and _import_stage(m) not in allowed)
    assert not wrong, '%s (%s) imports %s against the data flow; allowed: %s' % (
        os.path.relpath(path, ROOT), stage, ', '.join(wrong), ', '.join(sorted(allowed)) or 'nothing of anafi_sim')


def test_nothing_imports_the_nodes():
    offenders = [os.path.relpath(p, ROOT) for p in ALL_PY
                 if any(m.startswith('anafi_sim.scripts') for m in _imports(p, full=True))]
    assert not offenders


def test_the_stage_rule_can_fail():
    """The rule above is not vacuous: an upstream stage importing a downstream one is refused."""
    assert _import_stage('anafi_sim.experiments.trajectory') not in ALLOWED_IMPORTS[_SIM]
    assert _import_stage('anafi_sim.ros.node') not in ALLOWED_IMPORTS[_EXP]
    assert ALLOWED_IMPORTS[_CTL] == set()


@pytest.mark.parametrize('path', SCRIPTS, ids=[os.path.relpath(p, ROOT) for p in SCRIPTS])
def test_scripts_are_executable_python3(path):
    with open(path) as f:
        assert f.readline().strip() == '#!/usr/bin/env python3'
    assert os.access(path, os.X_OK)


@pytest.mark.parametrize('path', ALL_PY, ids=[os.path.relpath(p, ROOT) for p in ALL_PY])
def test_parses_as_python_3_8(path):
    ast.parse(open(path).read(), filename=path, feature_version=(3, 8))

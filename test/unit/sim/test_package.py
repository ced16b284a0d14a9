"""Package-level checks: catkin_lint, pure cores, nodes and their thin scripts, Python 3.8 syntax."""
import ast
import glob
import os
import re
import shutil
import subprocess
import sys

import pytest
from conftest import ROOT


def _stage(path):
    """The stage a module belongs to: 'anafi_control', 'anafi_sim.<subpackage or module>', 'anafi_lab.<room>'
    (a lab room: a subpackage or paper.py), ..."""
    parts = os.path.relpath(path, ROOT)[:-3].split(os.sep)
    if parts[0] == 'anafi_control':
        return parts[0]
    return parts[0] if parts[1] == '__init__' else parts[0] + '.' + parts[1]


def _py_files(*folders):
    return sorted(p for folder in folders for p in glob.glob(os.path.join(ROOT, folder, '**', '*.py'), recursive=True))


#: the stages that may use rospy: the ROS glue (ros/), the nodes (nodes/: each node's class and main()) and the
#: scripts that run them (scripts/)
ROS_STAGES = ('anafi_sim.ros', 'anafi_sim.nodes', 'anafi_sim.scripts')
#: pure cores: every module of anafi_sim (recursively) but ROS_STAGES, the control library and the lab
CORE_MODULES = [p for p in _py_files('anafi_sim', 'anafi_control', 'anafi_lab') if _stage(p) not in ROS_STAGES]
FLIGHT_MODULES = _py_files('anafi_sim', 'anafi_control')
LAB_MODULES = _py_files('anafi_lab')
SCRIPTS = sorted(glob.glob(os.path.join(ROOT, 'anafi_sim', 'scripts', '*.py')))
#: scripts that keep a small main of their own over a core (no node class): the launch-argument check and the
#: telemetry CLI stand-in
THIN_TOOLS = ('check_launch_args.py', 'tlm_data_logger.py')
LAB_TOOLS = sorted(p for p in glob.glob(os.path.join(ROOT, 'anafi_lab', 'cli', '*.py')) if not p.endswith('__init__.py'))
ALL_PY = sorted(set(CORE_MODULES + SCRIPTS + glob.glob(os.path.join(ROOT, '**', '*.py'), recursive=True)))
ALL_PY = [p for p in ALL_PY if '/.venv/' not in p and '/.ws/' not in p]

_SIM, _TLM, _IF, _GZ, _MIS, _CTL, _PATHS, _NAMES, _PROC, _NUM, _RUN = (
    'anafi_sim.sim', 'anafi_sim.telemetry', 'anafi_sim.interface', 'anafi_sim.gazebo', 'anafi_sim.mission',
    'anafi_control', 'anafi_sim.paths', 'anafi_sim.names', 'anafi_sim.processes', 'anafi_sim.numeric',
    'anafi_sim.run_files')
#: the lab's rooms from the bottom up: each may import the rooms below it, none above
LAB_ROOMS = ('anafi_lab.paper', 'anafi_lab.engine', 'anafi_lab.fidelity', 'anafi_lab.calibration', 'anafi_lab.reports',
             'anafi_lab.cli')
_TRUST, _YAML, _UNTR = 'anafi_sim.trusted', 'anafi_sim.safe_yaml', 'anafi_sim.untrusted'
_FLIGHT_CORES = {_SIM, _TLM, _IF, _GZ, _MIS, _CTL, _PATHS, _NAMES, _PROC, _NUM, _RUN, 'anafi_sim.launch_check',
                 _TRUST, _YAML, _UNTR}
#: the one direction of the data flow: what each stage may import (besides itself). Simulated drone ->
#: telemetry -> interface -> gazebo mirror | controllers; the mission (scenarios, evaluation) on top;
#: ros/ (node glue) above all cores, nodes/ (the nodes) above ros/, scripts/ (their mains) on top; anafi_control stands alone; the lab (anafi_lab)
#: beside it all, on top of every core, and nothing of the flight stack imports it. Inside the lab one order of
#: rooms (LAB_ROOMS): the paper's data, the engine (with the closed-loop replay), fidelity, calibration, reports
#: (every plot and Markdown text), the command-line tools.
ALLOWED_IMPORTS = {
    'anafi_sim': set(),
    _CTL: set(),
    _PATHS: set(),
    _NAMES: set(),
    _PROC: set(),
    _NUM: set(),
    _RUN: set(),
    _TRUST: set(),
    _YAML: set(),
    _UNTR: set(),
    'anafi_sim.launch_check': {_CTL, _PATHS, _NUM, _RUN, _TRUST, _UNTR},
    _TLM: {_PATHS, _NUM},
    _SIM: {_TLM, _CTL, _PATHS, _NUM, _TRUST, _YAML},
    _IF: {_TLM, _CTL, _PATHS, _NUM, _TRUST},
    _GZ: {_IF, _TLM, _CTL, _PATHS, _NUM},
    _MIS: {_SIM, _TLM, _IF, _GZ, _CTL, _PATHS, _NAMES, _NUM, _RUN, 'anafi_sim.launch_check', _TRUST, _YAML},
}
for _i, _room in enumerate(LAB_ROOMS):
    ALLOWED_IMPORTS[_room] = _FLIGHT_CORES | set(LAB_ROOMS[:_i])
ALLOWED_IMPORTS['anafi_lab'] = set()


def _imports(path, full=False):
    """Top-level names (or, with ``full``, dotted module names, 'from anafi_sim import x' as anafi_sim.x, the same
    for anafi_lab)."""
    tree = ast.parse(open(path).read(), filename=path)
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(a.name if full else a.name.split('.')[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module if full else node.module.split('.')[0])
            if full and node.module in ('anafi_sim', 'anafi_lab'):
                names.update(node.module + '.' + a.name for a in node.names)
    return names


def _import_stage(module):
    parts = module.split('.')
    if parts[0] == 'anafi_control':
        return parts[0]
    if parts[0] in ('anafi_sim', 'anafi_lab') and len(parts) > 1:
        return parts[0] + '.' + parts[1]
    return None


def _stage_violations(path, stage=None):
    """Imports of ``path`` against the data flow (its stage from its place, or ``stage``)."""
    stage = stage or _stage(path)
    allowed = ALLOWED_IMPORTS.get(stage)
    assert allowed is not None, 'module outside the known stages (add it to ALLOWED_IMPORTS): %s' % path
    return sorted(m for m in _imports(path, full=True)
                  if _import_stage(m) not in (None, stage) and _import_stage(m) not in allowed)


def _lab_imports(paths):
    """Files among ``paths`` that import the lab."""
    return [p for p in paths if any(m.split('.')[0] == 'anafi_lab' for m in _imports(p, full=True))]


def _module_name(path):
    rel = os.path.relpath(path, ROOT)[:-3].split(os.sep)
    return '.'.join(rel[:-1] if rel[-1] == '__init__' else rel)


def _import_graph(paths):
    """{module: modules of ``paths`` it imports (top level or inside functions)}."""
    names = dict((_module_name(p), p) for p in paths)
    graph = {}
    for name, path in names.items():
        targets = set()
        for m in _imports(path, full=True):
            while m and m not in names:
                m = m.rpartition('.')[0]
            if m and m != name and not names[m].endswith('__init__.py'):
                targets.add(m)
        graph[name] = targets
    return graph


def _cycles(graph):
    """Strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


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
    wrong = _stage_violations(path)
    assert not wrong, '%s (%s) imports %s against the data flow; allowed: %s' % (
        os.path.relpath(path, ROOT), _stage(path), ', '.join(wrong),
        ', '.join(sorted(ALLOWED_IMPORTS[_stage(path)])) or 'nothing of anafi_sim')


#: where the nodes (anafi_sim.nodes) may be imported: their scripts, the nodes themselves (the fleet host names
#: its hosted classes by module), tests and benchmarks
NODE_IMPORTERS = ('anafi_sim/scripts/', 'anafi_sim/nodes/', 'test/', 'benchmarks/')
#: most lines of a script of anafi_sim/scripts: a docstring and a main
SCRIPT_LINES = 40


def _imports_nodes(path):
    return any(m == 'anafi_sim.nodes' or m.startswith('anafi_sim.nodes.') for m in _imports(path, full=True))


def test_nothing_imports_the_scripts():
    offenders = [os.path.relpath(p, ROOT) for p in ALL_PY
                 if any(m.startswith('anafi_sim.scripts') for m in _imports(p, full=True))]
    assert not offenders


def test_only_scripts_nodes_and_tests_import_the_nodes():
    """The cores, the ROS glue and the lab never import a node (the glue is below the nodes)."""
    offenders = [os.path.relpath(p, ROOT) for p in ALL_PY
                 if not os.path.relpath(p, ROOT).startswith(NODE_IMPORTERS) and _imports_nodes(p)]
    assert not offenders


@pytest.mark.parametrize('path', SCRIPTS, ids=[os.path.relpath(p, ROOT) for p in SCRIPTS])
def test_scripts_are_thin(path):
    """A script is a main of a few lines; its node's class and logic live in anafi_sim.nodes (or a core)."""
    with open(path) as f:
        lines = f.read().splitlines()
    assert len(lines) <= SCRIPT_LINES, '%s has %d lines (at most %d: move its logic to anafi_sim/nodes)' % (
        os.path.relpath(path, ROOT), len(lines), SCRIPT_LINES)
    assert not [c for c in ast.parse('\n'.join(lines)).body if isinstance(c, (ast.ClassDef, ast.FunctionDef))
                and os.path.basename(path) not in THIN_TOOLS], 'a class or function in %s' % path


NODE_MODULES = sorted(glob.glob(os.path.join(ROOT, 'anafi_sim', 'nodes', '*.py')))


@pytest.mark.parametrize('path', NODE_MODULES, ids=[os.path.relpath(p, ROOT) for p in NODE_MODULES])
def test_node_modules_are_not_executable(path):
    """rosrun and roslaunch look for an executable of the type's name anywhere in the package: only the script
    may be one (an executable module of the same name makes rosrun ask which one to run)."""
    assert not os.access(path, os.X_OK), '%s is executable (chmod -x: its script runs it)' % path


def test_no_module_is_loaded_from_a_file_path():
    """Modules are imported by name (no run_path of a script, no sys.path edit to reach scripts/)."""
    word = 'run' + 'py'
    offenders = [os.path.relpath(p, ROOT) for p in _py_files('anafi_sim', 'anafi_control', 'anafi_lab', 'test',
                                                             'benchmarks', 'tools')
                 if word in open(p).read()]
    assert not offenders, 'files that use %s: %s' % (word, offenders)


def test_no_code_or_test_edits_sys_path():
    """The package, the lab and the tests import by name: no sys.path.insert / append (a test loads a tool or a
    benchmark with conftest.load_script; a rostest script finds the scripts beside it on its own path)."""
    pattern = re.compile(r'sys\.path\.(insert|append|extend)\(|sys\.path\s*=|syspath_prepend')
    offenders = [os.path.relpath(p, ROOT) for p in _py_files('anafi_sim', 'anafi_control', 'anafi_lab', 'test')
                 if p != os.path.abspath(__file__) and pattern.search(open(p).read())]
    assert not offenders, 'files that edit sys.path: %s' % offenders


def test_the_flight_stack_never_imports_the_lab():
    """What flies (anafi_sim with its nodes and glue, anafi_control) works without anafi_lab."""
    assert not [os.path.relpath(p, ROOT) for p in _lab_imports(FLIGHT_MODULES)]


def test_the_lab_imports_no_rospy():
    assert not [os.path.relpath(p, ROOT) for p in LAB_MODULES if 'rospy' in _imports(p)]


def test_no_import_cycles():
    assert not _cycles(_import_graph(FLIGHT_MODULES + LAB_MODULES))


def test_the_stage_rule_can_fail(tmp_path):
    """Each rule above is not vacuous: a module that breaks it is found."""
    assert _import_stage('anafi_sim.mission.trajectory') not in ALLOWED_IMPORTS[_SIM]
    assert _import_stage('anafi_sim.ros.node') not in ALLOWED_IMPORTS[_MIS]
    assert ALLOWED_IMPORTS[_CTL] == set()
    upstream = tmp_path / 'drone.py'
    upstream.write_text('from anafi_sim.mission.trajectory import Scenario\n')
    assert _stage_violations(str(upstream), _SIM) == ['anafi_sim.mission.trajectory']
    flight = tmp_path / 'node.py'
    flight.write_text('def f():\n    from anafi_lab.engine import runs\n')
    assert _lab_imports([str(flight)]) == [str(flight)]
    lab = tmp_path / 'lab.py'
    lab.write_text('import rospy\n')
    assert 'rospy' in _imports(str(lab))
    assert _cycles({'a': {'b'}, 'b': {'c'}, 'c': {'a'}, 'd': {'a'}}) == [['a', 'b', 'c']]
    assert _cycles({'a': {'b'}, 'b': set()}) == []
    assert _import_stage('anafi_lab.reports.paper_tables') not in ALLOWED_IMPORTS['anafi_lab.engine']
    back_up = tmp_path / 'engine_room.py'
    back_up.write_text('def f():\n    from anafi_lab.reports import paper_tables\n')
    assert _stage_violations(str(back_up), 'anafi_lab.fidelity') == ['anafi_lab.reports']
    glue = tmp_path / 'glue.py'
    glue.write_text('from anafi_sim.nodes.interface_node import InterfaceNode\n')
    assert _imports_nodes(str(glue)) and not _imports_nodes(str(lab))


@pytest.mark.parametrize('path', LAB_TOOLS, ids=[os.path.relpath(p, ROOT) for p in LAB_TOOLS])
def test_lab_tools_are_executable_python3(path):
    with open(path) as f:
        assert f.readline().strip() == '#!/usr/bin/env python3'
    assert os.access(path, os.X_OK)


@pytest.mark.parametrize('path', SCRIPTS, ids=[os.path.relpath(p, ROOT) for p in SCRIPTS])
def test_scripts_are_executable_python3(path):
    with open(path) as f:
        assert f.readline().strip() == '#!/usr/bin/env python3'
    assert os.access(path, os.X_OK)


@pytest.mark.parametrize('path', ALL_PY, ids=[os.path.relpath(p, ROOT) for p in ALL_PY])
def test_parses_as_python_3_8(path):
    ast.parse(open(path).read(), filename=path, feature_version=(3, 8))

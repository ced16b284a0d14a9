"""The docs stay true to the code: README.md and the pages of docs/ written by hand.

- every node script in anafi_sim/scripts has a section in docs/nodes.md (a heading naming it), and every
  private parameter its node (the module of anafi_sim/nodes it runs) reads (through ``anafi_sim.ros.params.ParamReader`` or ``rospy.get_param('~...')``,
  found statically, loops and helper functions resolved) appears as `name` in that section; every node is
  named in the README's node table and every command-line tool (anafi_sim/scripts, anafi_lab/cli) has a
  usage line there;
- every launch file is in the launch table of docs/launch.md, and the table names no other;
- the module tree of docs/architecture.md names every module of anafi_sim/, anafi_control/ and anafi_lab/ (but
  __init__.py and the thin scripts/) with its job, and nothing that does not exist;
- every repository path named in README.md and the hand-written docs (`anafi_sim/...`, `benchmarks/...`, ...)
  exists, and every link to a section leads to a heading;
- the README's architecture diagram names the stage folders, and only real ones.
"""
import ast
import builtins
import glob
import importlib.util
import inspect
import os
import re

import pytest

from anafi_sim.ros.params import ParamReader
from conftest import ROOT

SCRIPTS_DIR = os.path.join(ROOT, 'anafi_sim', 'scripts')
LAUNCH_DIR = os.path.join(ROOT, 'anafi_sim', 'launch')
README = os.path.join(ROOT, 'README.md')
NODES_DOC = os.path.join(ROOT, 'docs', 'nodes.md')
ARCHITECTURE_DOC = os.path.join(ROOT, 'docs', 'architecture.md')
LAUNCH_DOC = os.path.join(ROOT, 'docs', 'launch.md')
#: the pages written by hand (docs/calibration.md and docs/fidelity.md are generated reports)
HAND_WRITTEN = ['README.md', 'docs/install.md', 'docs/launch.md', 'docs/nodes.md', 'docs/architecture.md',
                'docs/experiments.md', 'docs/benchmarks.md', 'docs/fleet.md', 'docs/two_hosts.md', 'docs/reliability.md']

#: command-line tools in anafi_sim/scripts (not ROS nodes): a usage line in the README each
TOOLS = ('check_launch_args.py', 'echo.py', 'evaluate_log.py', 'record_bag.py', 'tlm_data_logger.py')
#: the lab's command-line tools (anafi_lab/cli, installed beside the nodes): a usage line in the README each
LAB_TOOLS = ('calibrate_conditions.py', 'calibrate_model.py', 'experiment.py', 'measure_fidelity.py', 'ros_batch.py')
LAB_CLI_DIR = os.path.join(ROOT, 'anafi_lab', 'cli')

#: the ParamReader's reading methods (number, positive, flag, string, ros_name, vector, choice, names, ...)
READER_METHODS = frozenset(name for name, _ in inspect.getmembers(ParamReader, inspect.isfunction)
                           if not name.startswith('_'))
#: rospy calls whose first argument names a parameter
ROSPY_PARAM_CALLS = frozenset(('get_param', 'has_param'))


def _read(path):
    with open(path) as f:
        return f.read()


def _script(name):
    return os.path.join(SCRIPTS_DIR, name)


def script_names():
    """The nodes and tools of anafi_sim/scripts (the lab's tools are LAB_TOOLS, in anafi_lab/cli)."""
    return sorted(os.path.basename(p) for p in glob.glob(os.path.join(SCRIPTS_DIR, '*.py')))


def node_scripts():
    return [name for name in script_names() if name not in TOOLS]


# ---------------------------------------------------------------------------------------------- extractor
class Unresolved(Exception):
    """A parameter-name expression the extractor cannot turn into names."""


class ParamExtractor(object):
    """Private parameter names a node script reads, found in its source.

    Calls ``X.<ParamReader method>(name, ...)``, ``rospy.get_param('~name', ...)`` /
    ``rospy.has_param('~name')`` and a NodeContext's ``ctx.get_param(name, ...)`` / ``ctx.has_param(name)``
    (also ``self.ctx``, ``self.node.ctx``: private names without the '~'). A name that is not a literal
    (``p.number(k, v) for k, v in SETTINGS.items()``, ``'%s_topic' % k``, ``'~' + k`` for ``k in self.PARAM_NAMES``, a helper's argument) is resolved by
    evaluating the loops that bind it in the script's namespace (the script is loaded as a module, its
    ``__main__`` block does not run); a helper function's argument through the helper's call sites. What
    cannot be resolved raises ``Unresolved``: then extend this class rather than let a parameter go
    unchecked. A script reads the parameters of the nodes it imports its main from (``from
    anafi_sim.nodes.X import main``: anafi_sim/nodes/X.py).
    """

    def __init__(self, path):
        self.path = path
        self.tree = ast.parse(_read(path), filename=path)
        self.parent = {}
        for node in ast.walk(self.tree):
            for child in ast.iter_child_nodes(node):
                self.parent[child] = node
        self._module = None

    # -- public
    def names(self):
        found = set()
        for call in self._param_calls():
            found.update(self._resolve(call.args[0], call, depth=0))
        for other in node_modules(self.tree):
            found.update(ParamExtractor(other).names())
        return found

    # -- calls
    def _param_calls(self):
        for node in ast.walk(self.tree):
            if not isinstance(node, ast.Call) or not isinstance(node.func, ast.Attribute) or not node.args:
                continue
            func = node.func
            if func.attr in READER_METHODS and isinstance(func.value, ast.Name) and self._is_reader(func.value):
                yield node
            elif func.attr in ROSPY_PARAM_CALLS and isinstance(func.value, ast.Name) and func.value.id == 'rospy' \
                    and self._is_private(node.args[0]):
                yield node
            elif func.attr in ROSPY_PARAM_CALLS and _is_context(func.value):
                yield node

    def _is_reader(self, name):
        """``name`` (an ast.Name) is a ParamReader: assigned from ``private_params()`` / ``ParamReader(...)``
        in its function, or an argument of it (``Adapter.build(self, p)``), never ``self`` or ``rospy``."""
        if name.id in ('self', 'rospy'):
            return False
        function = self._enclosing_function(name)
        if function is None:
            return False
        if name.id in [a.arg for a in function.args.args]:
            return True
        for node in ast.walk(function):
            if isinstance(node, ast.Assign) and isinstance(node.value, ast.Call) and any(
                    isinstance(t, ast.Name) and t.id == name.id for t in node.targets):
                called = node.value.func
                called = called.id if isinstance(called, ast.Name) else getattr(called, 'attr', '')
                if called in ('private_params', 'ParamReader'):
                    return True
        return False

    @staticmethod
    def _is_private(expr):
        """'~name' or '~' + expr (a private name); not '/global' names, not a bare variable."""
        if isinstance(expr, ast.Constant) and isinstance(expr.value, str):
            return expr.value.startswith('~')
        if isinstance(expr, ast.BinOp) and isinstance(expr.op, ast.Add):
            return ParamExtractor._is_private(expr.left)
        return False

    # -- resolution
    def module(self):
        """The script loaded as a module (not as __main__), for evaluating loop iterables."""
        if self._module is None:
            stem = os.path.splitext(os.path.basename(self.path))[0]
            spec = importlib.util.spec_from_file_location('_readme_check_' + stem, self.path)
            module = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(module)
            self._module = module
        return self._module

    def _where(self, node):
        return '%s:%d' % (os.path.relpath(self.path, ROOT), getattr(node, 'lineno', 0))

    def _resolve(self, expr, at, depth):
        """The parameter names ``expr`` (evaluated at node ``at``) can take."""
        if depth > 5:
            raise Unresolved('%s: parameter name resolution too deep' % self._where(at))
        if isinstance(expr, ast.Constant) and isinstance(expr.value, str):
            return {expr.value.lstrip('~')}
        free = _names(expr)
        function = self._enclosing_function(at)
        arguments = set(a.arg for a in function.args.args) if function is not None else set()
        helper_args = free & arguments
        if helper_args:
            if len(helper_args) != 1 or not isinstance(expr, (ast.Name, ast.BinOp)):
                raise Unresolved('%s: parameter name %s' % (self._where(at), ast.dump(expr)))
            return self._resolve_through_callers(function, helper_args.pop(), expr, depth)
        names = set()
        for binding in self._bindings(at, free):
            value = self._eval(expr, binding, at)
            if not isinstance(value, str):
                raise Unresolved('%s: parameter name %r is not a string' % (self._where(at), value))
            names.add(value.lstrip('~'))
        return names

    def _resolve_through_callers(self, function, arg, expr, depth):
        """``expr`` uses argument ``arg`` of helper ``function``: resolve it at every call of the helper."""
        index = [a.arg for a in function.args.args].index(arg)
        offset = 1 if function.args.args and function.args.args[0].arg == 'self' else 0
        names = set()
        calls = [node for node in ast.walk(self.tree) if isinstance(node, ast.Call) and (
            (isinstance(node.func, ast.Name) and node.func.id == function.name) or
            (isinstance(node.func, ast.Attribute) and node.func.attr == function.name))]
        if not calls:
            raise Unresolved('%s: helper %s is never called' % (self._where(function), function.name))
        for call in calls:
            if len(call.args) <= index - offset:
                raise Unresolved('%s: call of %s without argument %s' % (self._where(call), function.name, arg))
            for value in self._resolve(call.args[index - offset], call, depth + 1):
                names.add(self._eval(expr, {arg: value}, call).lstrip('~'))
        return names

    def _enclosing_function(self, node):
        while node in self.parent:
            node = self.parent[node]
            if isinstance(node, (ast.FunctionDef, ast.Lambda)):
                return node if isinstance(node, ast.FunctionDef) else None
        return None

    def _enclosing_class(self, node):
        while node in self.parent:
            node = self.parent[node]
            if isinstance(node, ast.ClassDef):
                return node.name
        return None

    def _binders(self, at, free):
        """(target, iter, ifs) of the loops and comprehensions around ``at`` that bind the names ``free``
        (or names their iterables use), outermost first; and the names of ``free`` no loop binds."""
        binders, needed = [], set(free)
        node = at
        while node in self.parent:
            child, node = node, self.parent[node]
            loops = []
            if isinstance(node, (ast.GeneratorExp, ast.ListComp, ast.SetComp, ast.DictComp)):
                loops = [(g.target, g.iter, g.ifs) for g in reversed(node.generators) if child is not g.iter]
            elif isinstance(node, ast.For) and child in node.body:
                loops = [(node.target, node.iter, [])]
            for target, iterable, ifs in loops:
                if _names(target) & needed:
                    binders.append((target, iterable, ifs))
                    needed -= _names(target)
                    needed |= _names(iterable, *ifs)
        binders.reverse()
        return binders, needed - set(dir(builtins))

    def _bindings(self, at, free):
        binders, unbound = self._binders(at, free)
        if unbound and not binders:
            # a name from the module (a constant) is fine, a local variable is not
            module_names = set(vars(self.module()))
            if unbound - module_names:
                raise Unresolved('%s: parameter name uses %s, not bound by a loop'
                                 % (self._where(at), ', '.join(sorted(unbound - module_names))))
        bindings = [{}]
        for target, iterable, ifs in binders:
            expanded = []
            for binding in bindings:
                for item in self._eval(iterable, binding, at):
                    b = dict(binding)
                    self._assign(target, item, b, at)
                    # a condition asking the parameter server (rospy.has_param) may hold: keep the name
                    if all(self._eval(cond, b, at) for cond in ifs if not self._asks_rospy(cond)):
                        expanded.append(b)
            bindings = expanded
        return bindings

    @staticmethod
    def _asks_rospy(expr):
        """``expr`` asks the parameter server (rospy, or a NodeContext's has_param / get_param)."""
        return any((isinstance(n, ast.Name) and n.id == 'rospy') or (
            isinstance(n, ast.Attribute) and n.attr in ROSPY_PARAM_CALLS and _is_context(n.value))
            for n in ast.walk(expr))

    def _assign(self, target, value, binding, at):
        if isinstance(target, ast.Name):
            binding[target.id] = value
        elif isinstance(target, (ast.Tuple, ast.List)):
            values = list(value)
            if len(values) != len(target.elts):
                raise Unresolved('%s: cannot unpack %r' % (self._where(at), value))
            for t, v in zip(target.elts, values):
                self._assign(t, v, binding, at)
        else:
            raise Unresolved('%s: loop target %s' % (self._where(at), ast.dump(target)))

    def _eval(self, expr, binding, at):
        if not binding:
            try:
                return ast.literal_eval(expr)     # literal tuples need no import of the script
            except ValueError:
                pass
        return self._eval_in_module(expr, binding, at)

    def _eval_in_module(self, expr, binding, at):
        namespace = dict(vars(self.module()))
        cls = self._enclosing_class(at)
        if cls is not None:
            namespace['self'] = getattr(self.module(), cls)    # class attributes (e.g. self.PARAM_NAMES)
        namespace.update(binding)
        try:
            return eval(compile(ast.Expression(body=expr), self.path, 'eval'), namespace)
        except Exception as error:
            raise Unresolved('%s: cannot evaluate %s: %s' % (self._where(at), ast.dump(expr), error))


def node_modules(tree):
    """The files of the anafi_sim.nodes modules the module ``tree`` imports from."""
    return sorted(set(os.path.join(ROOT, *node.module.split('.')) + '.py' for node in ast.walk(tree)
                      if isinstance(node, ast.ImportFrom) and (node.module or '').startswith('anafi_sim.nodes.')))


def _is_context(expr):
    """``expr`` is a NodeContext: the name ``ctx`` or an attribute ``....ctx``."""
    return (isinstance(expr, ast.Name) and expr.id == 'ctx') or (isinstance(expr, ast.Attribute) and expr.attr == 'ctx')


def _names(*exprs):
    """The names (ast.Name ids) used in ``exprs``."""
    return set(n.id for e in exprs for n in ast.walk(e) if isinstance(n, ast.Name))


def param_names(script):
    """The private parameter names node ``script`` (file name in anafi_sim/scripts) reads."""
    return ParamExtractor(_script(script)).names()


# ---------------------------------------------------------------------------------------------- doc sections
_HEADING = re.compile(r'^(#{1,6})\s+(.*)$')


def sections(text):
    """[(level, heading, body)] of a Markdown text (body up to the next heading of the same or higher level)."""
    lines = text.splitlines()
    heads = [(i, len(m.group(1)), m.group(2)) for i, m in ((i, _HEADING.match(l)) for i, l in enumerate(lines))
             if m and not _in_code_block(lines, i)]
    out = []
    for k, (i, level, title) in enumerate(heads):
        end = next((j for j, lvl, _ in heads[k + 1:] if lvl <= level), len(lines))
        out.append((level, title, '\n'.join(lines[i + 1:end])))
    return out


def _in_code_block(lines, index):
    return sum(1 for line in lines[:index] if line.lstrip().startswith('```')) % 2 == 1


def node_section(text, script):
    """Body of the section whose heading names `script` (None when there is none)."""
    for _, title, body in sections(text):
        if '`%s`' % script in title:
            return body
    return None


def missing_params(section, names):
    """The names that do not appear as `name` in ``section``."""
    return sorted(n for n in names if '`%s`' % n not in section)


# ---------------------------------------------------------------------------------------------- the checks
def test_the_extractor_finds_literal_looped_and_helper_parameters():
    """Not vacuous: known parameters of several nodes are found, by each way the nodes read them."""
    interface = param_names('interface_node.py')
    assert {'telemetry_command', 'prefix', 'camera_offset', 'frame_id', 'drone_name',
            'stamp_with_sample_time'} <= interface                             # literal names
    assert {'rate', 'stale_timeout', 'restart_timeout', 'backoff_initial', 'backoff_max'} <= interface   # a loop
    sim = param_names('anafi_sim_node.py')
    assert {'rate', 'rtf', 'model', 'wind_x', 'command_timeout', 'max_specific_thrust'} <= sim   # DEFAULT_SETTINGS
    controller = param_names('controller_node.py')
    assert {'controller', 'rate', 'N', 'q_cum', 'v_max_z', 'polish', 'yaw', 'x_outer', 'vertical'} <= controller
    assert 'v_max' not in controller                                            # the comprehension's condition
    evaluator = param_names('evaluator.py')
    assert {'waypoint_topic', 'truth_topic', 'begin_topic'} <= evaluator         # '%s_topic' % k in a loop
    assert {'summary_file', 'csv_file', 'plot_file', 'info_file'} <= param_names('experiment_monitor.py')
    assert {'Kp', 'angle_wrap', 'setpoint_topic'} <= param_names('pid_controller.py')   # module-level tables
    assert param_names('mpc_controller.py') == controller                       # main of another node
    assert param_names('tlm_data_logger.py') == set()
    assert '/use_sim_time' not in param_names('anafi_sim_node.py') and 'use_sim_time' not in sim


def test_the_extractor_refuses_what_it_cannot_resolve(tmp_path):
    path = tmp_path / 'node.py'
    path.write_text('def f(p, x):\n    return p.number(x.name, 1.0)\n')
    with pytest.raises(Unresolved):
        ParamExtractor(str(path)).names()


def test_a_missing_parameter_is_reported():
    assert missing_params('| `rate` | double | 10 |', {'rate', 'stale_timeout'}) == ['stale_timeout']
    text = '# A\n## `a.py` x\nbody `p`\n```\n# not a heading\n```\n## `b.py`\nother\n'
    assert '`p`' in node_section(text, 'a.py') and 'not a heading' in node_section(text, 'a.py')
    assert node_section(text, 'b.py').strip() == 'other'
    assert node_section(text, 'c.py') is None


def test_tools_and_nodes_cover_every_script():
    scripts = script_names()
    assert set(TOOLS) <= set(scripts), 'a tool was renamed or removed: update TOOLS and the README'
    lab = set(os.path.basename(p) for p in glob.glob(os.path.join(LAB_CLI_DIR, '*.py'))) - {'__init__.py'}
    assert set(LAB_TOOLS) == lab, 'a lab tool was added, renamed or removed: update LAB_TOOLS and the README'
    for name in node_scripts():
        modules = node_modules(ast.parse(_read(_script(name))))
        assert modules and all('run_node(' in _read(m) for m in modules), \
            '%s does not run a node of anafi_sim/nodes (run_node): add it to TOOLS or make it a node' % name


@pytest.mark.parametrize('script', node_scripts())
def test_every_node_has_a_section_listing_its_parameters(script):
    text = _read(NODES_DOC)
    section = node_section(text, script)
    assert section is not None, 'docs/nodes.md has no section whose heading names `%s`' % script
    for part in ('Subscribed topics', 'Published topics', 'Parameters'):
        assert part in section, 'docs/nodes.md, section of %s: no "%s"' % (script, part)
    missing = missing_params(section, param_names(script))
    assert not missing, 'docs/nodes.md, section of %s: parameters not documented: %s' % (
        script, ', '.join('`%s`' % n for n in missing))


@pytest.mark.parametrize('script', node_scripts())
def test_every_node_has_a_line_in_the_readme(script):
    assert '`%s`' % script in _read(README), 'README.md does not name the node %s' % script


@pytest.mark.parametrize('tool', TOOLS + LAB_TOOLS)
def test_every_tool_has_a_usage_line_in_the_readme(tool):
    readme = _read(README)
    assert re.search(r'`[^`\n]*%s[^`\n]*`' % re.escape(tool), readme) and tool in readme, tool
    assert any(tool in line and ('[' in line or '-' in line) for line in readme.splitlines()
               if not line.startswith('#')), 'README.md: no usage line for %s' % tool


def test_every_launch_file_is_in_the_launch_table():
    rows = set(re.findall(r'^\|\s*`([\w.]+\.launch)`', _read(LAUNCH_DOC), re.M))
    files = set(os.path.basename(p) for p in glob.glob(os.path.join(LAUNCH_DIR, '*.launch')))
    assert files - rows == set(), 'launch files missing from the table of docs/launch.md: %s' % sorted(files - rows)
    assert rows - files == set(), 'docs/launch.md\'s table names files that do not exist: %s' % sorted(rows - files)


def _modules():
    found = []
    for root in ('anafi_sim', 'anafi_control', 'anafi_lab'):
        for path in glob.glob(os.path.join(ROOT, root, '**', '*.py'), recursive=True):
            rel = os.path.relpath(path, ROOT)
            if os.path.basename(rel) != '__init__.py' and not rel.startswith(os.path.join('anafi_sim', 'scripts')):
                found.append(rel)
    return sorted(found)


_TREE_LINE = re.compile(r'^( *)([\w.]+/?)(?: {2,}(\S.*))?$')


def module_tree(text):
    """{path: job} of the module tree (the code block after '## Modules'): 2 spaces of indent per level,
    folders end in '/', each entry 'name   job'."""
    body = next((b for _, title, b in sections(text) if title.strip() == 'Modules'), None)
    assert body is not None, 'docs/architecture.md has no "## Modules" section'
    block = re.search(r'```\n(.*?)```', body, re.S)
    assert block, 'docs/architecture.md, "Modules": no code block with the tree'
    entries, stack = {}, []
    for line in block.group(1).splitlines():
        m = _TREE_LINE.match(line)
        assert m and len(m.group(1)) % 2 == 0, 'docs/architecture.md, module tree: unreadable line %r' % line
        depth = len(m.group(1)) // 2
        assert depth <= len(stack), 'docs/architecture.md, module tree: %r is indented too deep' % line
        stack[depth:] = [m.group(2).rstrip('/')]
        entries['/'.join(stack)] = (m.group(3) or '').strip()
    return entries


def test_module_tree_reader():
    tree = module_tree('## Modules\n```\na/   A\n  b.py   B job\n  c/\n    d.py  D\ne.py  E\n```\n')
    assert tree == {'a': 'A', 'a/b.py': 'B job', 'a/c': '', 'a/c/d.py': 'D', 'e.py': 'E'}


def test_architecture_doc_lists_every_module_and_only_real_ones():
    text = _read(ARCHITECTURE_DOC)
    tree = module_tree(text)
    absent = sorted(p for p in tree if not os.path.exists(os.path.join(ROOT, p)))
    assert not absent, 'docs/architecture.md, module tree: no such file or folder: %s' % absent
    modules = [p for p in tree if p.endswith('.py')]
    jobless = sorted(p for p in modules if not tree[p])
    assert not jobless, 'docs/architecture.md, module tree: modules without their job: %s' % jobless
    unlisted = [m for m in _modules() if m not in tree]
    assert not unlisted, 'modules missing from the tree in docs/architecture.md: %s' % unlisted
    named = set(re.findall(r'((?:anafi_sim|anafi_control|anafi_lab)/[\w/]+\.py)', text))   # also in the prose
    assert not sorted(p for p in named if not os.path.isfile(os.path.join(ROOT, p)))


_TOP = ('anafi_sim', 'anafi_control', 'anafi_lab', 'benchmarks', 'test', 'tools', 'docs', 'msg', 'cfg')
_ROS_TYPE = re.compile(r'^\w+/[A-Z]\w*$')
_PATH = re.compile(r'`((?:%s)/[^`\s]*)`' % '|'.join(_TOP))


def _expand(pattern):
    """'a/{b,c}.md' -> ['a/b.md', 'a/c.md']."""
    m = re.search(r'\{([^{}]*)\}', pattern)
    if not m:
        return [pattern]
    return [p for alt in m.group(1).split(',') for p in _expand(pattern[:m.start()] + alt + pattern[m.end():])]


@pytest.mark.parametrize('doc', HAND_WRITTEN)
def test_repository_paths_in_the_docs_exist(doc):
    text = _read(os.path.join(ROOT, doc))
    absent = []
    for raw in set(_PATH.findall(text)):
        path = raw.split(' ')[0].rstrip('.,:;)')
        if _ROS_TYPE.match(path):       # anafi_sim/Waypoint: a message type, not a path
            continue
        for candidate in _expand(path):
            if not glob.glob(os.path.join(ROOT, candidate)):
                absent.append(candidate)
    assert not absent, '%s names paths that do not exist: %s' % (doc, sorted(absent))


def test_readme_architecture_diagram_names_real_folders():
    readme = _read(README)
    arch = next((body for level, title, body in sections(readme) if title.strip() == 'Architecture'), None)
    assert arch is not None, 'README.md has no "## Architecture" section'
    diagram = re.search(r'```\n(.*?)```', arch, re.S)
    assert diagram, 'the Architecture section has no diagram'
    folders = set(re.findall(r'\b((?:anafi_sim/\w+|anafi_control|anafi_lab))\b', diagram.group(1)))
    expected = {'anafi_sim/sim', 'anafi_sim/telemetry', 'anafi_sim/interface', 'anafi_sim/gazebo', 'anafi_control',
                'anafi_sim/mission', 'anafi_lab', 'anafi_sim/ros', 'anafi_sim/nodes', 'anafi_sim/scripts'}
    assert expected <= folders, 'diagram lacks %s' % sorted(expected - folders)
    absent = sorted(f for f in folders if not os.path.isdir(os.path.join(ROOT, f)))
    assert not absent, 'diagram names folders that do not exist: %s' % absent


def anchor(title):
    """GitHub's anchor of a Markdown heading: lower case, punctuation dropped, spaces -> '-'."""
    return re.sub(r'[^\w\- ]', '', title.strip().lower()).replace(' ', '-')


def test_anchor_rule():
    assert anchor("`anafi_sim_node.py` — the simulated Anafi") == 'anafi_sim_nodepy--the-simulated-anafi'
    assert anchor("The paper's distributed PID framework") == 'the-papers-distributed-pid-framework'


@pytest.mark.parametrize('doc', HAND_WRITTEN)
def test_links_to_sections_resolve(doc):
    """Links like (docs/nodes.md#evaluatorpy--live-tracking-error) or (#calibration) lead to a heading."""
    path = os.path.join(ROOT, doc)
    broken = []
    for target, frag in re.findall(r'\]\(([^)#\s]*)#([^)\s]+)\)', _read(path)):
        if '://' in target:
            continue
        linked = os.path.normpath(os.path.join(os.path.dirname(path), target)) if target else path
        if not os.path.isfile(linked) or frag not in [anchor(t) for _, t, _ in sections(_read(linked))]:
            broken.append('%s#%s' % (target, frag))
    assert not broken, '%s: links to missing sections: %s' % (doc, broken)

"""The commands and paths the documentation shows exist: README.md and docs/*.md, their code blocks and code spans.

- ``roslaunch anafi_sim FILE ...``: FILE is a launch file of the package and every ``NAME:=`` is an argument it
  declares (roslaunch would ignore another; the launch check refuses it);
- ``rosrun anafi_sim TOOL``: TOOL is a script of the package; ``rosrun PKG EXE`` of another package: where PKG
  is installed here, EXE is one of its executables (Debian's rosdiagnostic, for one, ships none);
- a path of the repository (``anafi_sim/...``, ``anafi_lab/...``, ``benchmarks/...``, ``tools/...``,
  ``docs/...``, ``test/...``, ``cfg/...``) in a code block or span exists, unless it holds a placeholder;
- a run's file under ``~/.ros/anafi_demo`` or ``~/.ros/anafi_runs`` is named in its run folder (``latest/``):
  every run writes into a folder of its own.
"""
import glob
import os
import re
import shlex

import pytest

from anafi_sim.launch_check import declared_arguments
from conftest import ROOT

DOCS = [os.path.join(ROOT, 'README.md')] + sorted(glob.glob(os.path.join(ROOT, 'docs', '*.md')))
FENCE = re.compile(r'^```[^\n]*\n(.*?)^```', re.M | re.S)
SPAN = re.compile(r'`([^`\n]+)`')
ARG = re.compile(r'(?<![A-Za-z0-9_/~.-])([A-Za-z_][A-Za-z0-9_]*):=')
REPO_PATH = re.compile(r'(?<![A-Za-z0-9_/.~-])((?:anafi_sim|anafi_lab|anafi_control|benchmarks|tools|docs|test|cfg)'
                       r'/[A-Za-z0-9_./-]*[A-Za-z0-9_])')
#: text in a path that stands for something (a name to choose, a pattern, a folder a run makes)
PLACEHOLDER = re.compile(r'[<>{}*]|\.\.\.|NAME|DRONE|RUN|[A-Z]{3,}')
RUN_FILE = re.compile(r'~/\.ros/anafi_(?:demo|runs)/[^/\s`]+\.(?:bag|csv|yaml|png)\b')


def snippets(path):
    """(kind, text) of the code blocks ('block', one logical line each: continuation lines joined) and code
    spans ('span') of the Markdown file at ``path``."""
    with open(path) as f:
        text = f.read()
    out = []
    for block in FENCE.findall(text):
        for line in block.replace('\\\n', ' ').splitlines():
            out.append(('block', line.split(' #', 1)[0] if not line.lstrip().startswith('#') else ''))
    for span in SPAN.findall(FENCE.sub('', text)):
        out.append(('span', span))
    return out


def all_snippets():
    return [(os.path.relpath(path, ROOT), kind, text) for path in DOCS for kind, text in snippets(path)]


def words_after(text, *command):
    """The words after ``command`` (a word sequence) in ``text``, or None when it does not hold it."""
    try:
        words = shlex.split(text, comments=False)
    except ValueError:
        words = text.split()
    n = len(command)
    for i in range(len(words) - n + 1):
        if tuple(words[i:i + n]) == command:
            return words[i + n:]
    return None


def launch_args(name):
    with open(os.path.join(ROOT, 'anafi_sim', 'launch', name)) as f:
        return set(declared_arguments(f.read()))


def roslaunch_problems(doc, text):
    rest = words_after(text, 'roslaunch', 'anafi_sim')
    if not rest:
        return []
    name = rest[0].strip('`,;')
    if not name.endswith('.launch') or PLACEHOLDER.search(name):
        return []
    if not os.path.isfile(os.path.join(ROOT, 'anafi_sim', 'launch', name)):
        return ['%s: roslaunch anafi_sim %s: no such launch file' % (doc, name)]
    known = launch_args(name)
    words = []
    for word in rest[1:]:
        if word in ('&&', '||', '|', ';', '&'):       # the next command
            break
        words.append(word)
    return ['%s: roslaunch anafi_sim %s %s:=: not an argument of %s' % (doc, name, arg, name)
            for arg in ARG.findall(' '.join(words)) if arg not in known]


def rosrun_problems(doc, text):
    rest = words_after(text, 'rosrun')
    if not rest or len(rest) < 2 or PLACEHOLDER.search(rest[1]):
        return []
    package, exe = rest[0], rest[1].strip('`,;')
    if package == 'anafi_sim':     # CMakeLists.txt installs these beside the nodes
        paths = [os.path.join(ROOT, 'anafi_sim', 'scripts', exe), os.path.join(ROOT, 'anafi_lab', 'cli', exe)]
        return [] if any(os.path.isfile(p) for p in paths) else \
            ['%s: rosrun anafi_sim %s: no such script in anafi_sim/scripts or anafi_lab/cli' % (doc, exe)]
    try:
        import rospkg
        folder = rospkg.RosPack().get_path(package)
    except Exception:
        folder = None
    if folder is None:
        import importlib.util
        if exe in executables(package, None):     # no package.xml (Debian's tf), rosrun still finds <prefix>/lib/tf
            return []
        if importlib.util.find_spec(package) is not None:    # a Python module, not a ROS package: no rosrun
            return ['%s: rosrun %s %s: %s is a Python module here, not a package rosrun finds'
                    % (doc, package, exe, package)]
        return []                                              # not installed here (Noetic-only): not checked
    return [] if exe in executables(package, folder) else \
        ['%s: rosrun %s %s: no such executable of %s here' % (doc, package, exe, package)]


def executables(package, folder):
    """The names of the executables rosrun finds for ``package`` (its folder ``folder``): below the folder, and
    in the package's libexec folders (<prefix>/lib/<package>) of the CMAKE_PREFIX_PATH and /usr."""
    found = set()
    prefixes = [p for p in os.environ.get('CMAKE_PREFIX_PATH', '').split(os.pathsep) if p] + ['/usr', '/opt/ros']
    for top in ([folder] if folder else []) + [os.path.join(p, 'lib', package) for p in prefixes]:
        for here, _, files in os.walk(top):
            found.update(f for f in files if os.access(os.path.join(here, f), os.X_OK))
    return found


def path_problems(doc, text):
    out = []
    for path in REPO_PATH.findall(text):
        if PLACEHOLDER.search(path) or re.match(r'^[a-z_]+/[A-Z][A-Za-z0-9]*$', path):
            continue                   # a placeholder; a message type (anafi_sim/Waypoint)
        if not os.path.exists(os.path.join(ROOT, path)):
            out.append('%s: %s: no such file or folder' % (doc, path))
    for run_file in RUN_FILE.findall(text):
        out.append('%s: %s: a run\'s files are in its own folder (%s)'
                   % (doc, run_file, run_file.replace('/anafi_', '/anafi_').rsplit('/', 1)[0] + '/latest/...'))
    return out


def test_the_docs_show_commands():
    texts = [text for _, _, text in all_snippets()]
    assert sum('roslaunch anafi_sim' in t for t in texts) >= 20 and sum('rosrun ' in t for t in texts) >= 3


def test_every_roslaunch_command_names_a_launch_file_and_its_arguments():
    problems = [p for doc, _, text in all_snippets() for p in roslaunch_problems(doc, text)]
    assert problems == []


def test_every_rosrun_command_names_an_executable():
    problems = [p for doc, _, text in all_snippets() for p in rosrun_problems(doc, text)]
    assert problems == []


def test_every_repository_path_in_code_exists():
    problems = sorted(set(p for doc, _, text in all_snippets() for p in path_problems(doc, text)))
    assert problems == []


@pytest.mark.parametrize('text, bad', [
    ('roslaunch anafi_sim nope.launch', 'no such launch file'),
    ('roslaunch anafi_sim experiment.launch contoller:=pid', 'contoller:='),
    ('rosrun anafi_sim nope.py', 'no such script'),
    ('rosbag play ~/.ros/anafi_demo/circle_r2_v1_mpc.bag', 'own folder'),
    ('python anafi_lab/cli/nope.py', 'no such file'),
    ('rosrun dynamic_reconfigure nope', 'no such executable'),
])
def test_the_checks_find_what_is_wrong(text, bad):
    problems = roslaunch_problems('x', text) + rosrun_problems('x', text) + path_problems('x', text)
    assert len(problems) == 1 and bad in problems[0], problems


def test_the_checks_pass_what_is_right():
    for text in ('roslaunch anafi_sim experiment.launch controller:=pid scenario:=straight_3',
                 'rosrun anafi_sim echo.py /anafi/drone/rpyt', 'python anafi_lab/cli/measure_fidelity.py',
                 'rosbag play ~/.ros/anafi_demo/latest/circle_r2_v1_mpc.bag', 'anafi_sim/config/NAME.yaml'):
        assert roslaunch_problems('x', text) + rosrun_problems('x', text) + path_problems('x', text) == [], text


def test_the_launch_file_table_names_each_files_own_arguments():
    """docs/launch.md's table: an argument name of some launch file, in a file's row, is one of that file's."""
    every = set()
    for path in glob.glob(os.path.join(ROOT, 'anafi_sim', 'launch', '*.launch')):
        every |= launch_args(os.path.basename(path))
    problems, rows = [], 0
    with open(os.path.join(ROOT, 'docs', 'launch.md')) as f:
        for line in f:
            m = re.match(r'^\| `([a-z_]+\.launch)` \| (.*)\|\s*$', line)
            if not m:
                continue
            rows += 1
            own = launch_args(m.group(1))
            problems += ['%s: %s' % (m.group(1), name) for name in re.findall(r'`([a-z_]+)`', m.group(2))
                         if name in every and name not in own]
    assert rows == len(glob.glob(os.path.join(ROOT, 'anafi_sim', 'launch', '*.launch'))) and problems == []

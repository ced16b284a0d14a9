"""What the unit tests share: the repository root and a reader for the dynamic_reconfigure files in cfg/.

The tests are grouped by what they test: control/ (anafi_control), sim/ (the flight stack of anafi_sim and the
package as a whole), mission/ (anafi_sim.mission), lab/ (anafi_lab). Tests import ``ROOT`` and ``cfg_defaults``
from here (``from conftest import ROOT``); pytest puts this directory on ``sys.path``.
"""
import ast
import os

#: the repository root (the catkin package's directory)
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def repo_path(*parts):
    """The absolute path of ``parts`` below the repository root."""
    return os.path.join(ROOT, *parts)


def cfg_defaults(name):
    """{name: default} of every gen.add / group.add call in cfg/``name`` (read as text, not run)."""
    path = repo_path('cfg', name)
    with open(path) as f:
        tree = ast.parse(f.read(), filename=path)
    out = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == 'add' \
                and node.args and isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str):
            out[node.args[0].value] = ast.literal_eval(node.args[4])
    return out

"""What the unit tests share: the repository root and a reader for the dynamic_reconfigure files in cfg/.

The tests are grouped by what they test: control/ (anafi_control), sim/ (the flight stack of anafi_sim and the
package as a whole), mission/ (anafi_sim.mission), lab/ (anafi_lab). Tests import ``ROOT`` and ``cfg_defaults``
from here (``from conftest import ROOT``); pytest puts this directory on ``sys.path``. They compare rotations
with ``rotation_angle`` / ``quaternion_angle`` and bounds in units of ``EPS`` (see there), never with an arccos.

Property tests (hypothesis) run the same examples on every run and machine (profile ``repeatable``: a red CI
is reproducible, and no wall-clock deadline, so they pass under load); ``HYPOTHESIS_PROFILE=explore`` draws new
examples each run (random seed, more of them) to search for new failures.
"""
import ast
import math
import os

import numpy as np
from hypothesis import settings

settings.register_profile('repeatable', derandomize=True, deadline=None, database=None)
settings.register_profile('explore', deadline=None, max_examples=1000)
settings.load_profile(os.environ.get('HYPOTHESIS_PROFILE', 'repeatable'))

#: the repository root (the catkin package's directory)
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def repo_path(*parts):
    """The absolute path of ``parts`` below the repository root."""
    return os.path.join(ROOT, *parts)


def load_script(*parts):
    """The Python script at ``parts`` below the repository root (tools/, benchmarks/) as a module named after its
    file, kept in sys.modules so the scripts beside it that import it by name find it (load those first)."""
    import importlib.util
    import sys
    path = repo_path(*parts)
    name = os.path.splitext(os.path.basename(path))[0]
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


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


#: float64 machine epsilon (2.2e-16): the unit of the tolerances below
EPS = float(np.finfo(float).eps)

#: bound [rad] on the angle between two computations of one rotation from the same angles through different
#: formulas (sin/cos, quaternion products, matrix products through BLAS, a quaternion read from a matrix): each
#: entry of magnitude <= 1 carries a few tens of ulps of rounding, and the angle measures below are linear in
#: those errors (condition number ~1), so a few hundred ulps bound it on any CPU and BLAS kernel.
ROTATION_TOLERANCE = 256 * EPS


def rotation_angle(a, b):
    """Angle [rad] of the rotation between rotation matrices ``a`` and ``b``: atan2(|2 sin|, 2 cos) of the
    relative rotation a^T b, from its skew part and its trace. Well conditioned everywhere (an arccos of
    (trace - 1) / 2 turns rounding of order eps near 0 into an angle of order sqrt(eps) ~ 1e-8 rad)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    r = [[sum(a[k, i] * b[k, j] for k in range(3)) for j in range(3)] for i in range(3)]   # a^T b, no BLAS
    skew = math.sqrt((r[2][1] - r[1][2]) ** 2 + (r[0][2] - r[2][0]) ** 2 + (r[1][0] - r[0][1]) ** 2)
    return math.atan2(skew, r[0][0] + r[1][1] + r[2][2] - 1.0)


def quaternion_angle(qa, qb):
    """Angle [rad] of the rotation between unit quaternions ``qa`` and ``qb`` (x, y, z, w; q and -q alike):
    2 atan2(|v|, |w|) of the relative quaternion conj(qa) qb. Well conditioned everywhere, unlike
    2 acos(|qa . qb|) near 0."""
    x1, y1, z1, w1 = (float(v) for v in qa)
    x2, y2, z2, w2 = (float(v) for v in qb)
    w = w1 * w2 + x1 * x2 + y1 * y2 + z1 * z2
    x = w1 * x2 - x1 * w2 - y1 * z2 + z1 * y2
    y = w1 * y2 + x1 * z2 - y1 * w2 - z1 * x2
    z = w1 * z2 - x1 * y2 + y1 * x2 - z1 * w2
    return 2.0 * math.atan2(math.sqrt(x * x + y * y + z * z), abs(w))

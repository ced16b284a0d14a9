"""anafi_sim: simulated Anafi, Sphinx ground-truth interface and Gazebo mirror (pure cores).

The generated messages (``anafi_sim.msg``) live in the catkin devel/install
space; extend the package path so they are found whichever copy of this
package comes first on sys.path (e.g. pytest run from the source tree).

Importing it checks that ``anafi_control`` is this project's control library and not the paper authors'
message package of the same name found first on the path (README, "The anafi_control name clash"): every
node imports ``anafi_sim`` before ``anafi_control``, so it stops with that message instead of an ImportError.
"""
__path__ = __import__('pkgutil').extend_path(__path__, __name__)

CONTROL_LIBRARY_CLASH = (
    "anafi_sim: the Python package 'anafi_control' found first on the path (%s) is not this project's control "
    "library (it has no anafi_control.contract): most likely the paper authors' ROS message package "
    "anafi_control, whose workspace comes before anafi_sim's. Source their workspace's setup.bash first and "
    "anafi_sim's last (anafi_sim's then comes first and still finds their anafi_control.msg), or run their "
    "nodes from an isolated workspace; see README.md, 'The anafi_control name clash'.")


def _check_control_library():
    """SystemExit with CONTROL_LIBRARY_CLASH when the ``anafi_control`` found first is not ours."""
    import importlib
    import importlib.util
    try:
        found = importlib.util.find_spec('anafi_control.contract') is not None
    except ImportError:
        found = False
    if not found:
        try:
            package = importlib.import_module('anafi_control')
            where = ', '.join(getattr(package, '__path__', [])) or getattr(package, '__file__', '?')
        except ImportError:
            where = 'not importable'
        raise SystemExit(CONTROL_LIBRARY_CLASH % where)


_check_control_library()

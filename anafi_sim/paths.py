"""Where the package's data files are: found through the ROS package path, so devel and install spaces work.

``package_dir()`` is the folder that holds ``package.xml``: the source tree (devel space) or
``<install>/share/anafi_sim`` (install space, where CMakeLists.txt installs ``anafi_sim/config``,
``data``, ``launch`` and ``urdf`` under the same relative paths). Without a ROS environment (plain pytest on a
checkout) it falls back to the checkout this module was imported from.
"""
import functools
import os

PACKAGE = 'anafi_sim'


@functools.lru_cache(maxsize=None)
def package_dir():
    """Absolute path of the anafi_sim package folder (the one with package.xml)."""
    try:
        import rospkg
        path = rospkg.RosPack().get_path(PACKAGE)
        if os.path.isdir(os.path.join(path, PACKAGE, 'config')):
            return path
    except Exception:   # rospkg missing, or the package not on ROS_PACKAGE_PATH
        pass
    checkout = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    if os.path.isfile(os.path.join(checkout, 'package.xml')):
        return checkout
    raise RuntimeError('cannot find the %s package: source its setup.bash (devel or install space)' % PACKAGE)


def data_path(*parts):
    """Path of a data file of the package, e.g. ``data_path('config', 'mpc.yaml')`` [anafi_sim/config/mpc.yaml]."""
    return os.path.join(package_dir(), PACKAGE, *parts)


def config_path(*parts):
    """Path below ``anafi_sim/config``."""
    return data_path('config', *parts)


def checkout():
    """The folder of the package's sources (package.xml resolved, so a workspace's link leads to it)."""
    return os.path.dirname(os.path.realpath(os.path.join(package_dir(), 'package.xml')))


def reference_logs_dir(*parts):
    """``anafi_sim/data/reference_logs``: the paper's reference logs shipped with the package (its README says
    where they come from): the 14 Sphinx runs, ``reference_logs_dir('real')`` the four real flights."""
    return data_path('data', 'reference_logs', *parts)

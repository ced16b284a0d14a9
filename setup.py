# Used by catkin_python_setup() only (devel space: relays to this tree; `catkin_make install`: copies the
# packages to <install>/lib/python3/dist-packages); do not run directly.
# Every Python package below the two roots is shipped: anafi_sim with its stage subpackages
# (sim, telemetry, interface, gazebo, experiments, calibration, ros) and anafi_control. Data files
# (anafi_sim/{config,launch,urdf}) are not Python packages: CMakeLists.txt installs them under
# share/anafi_sim/anafi_sim, where anafi_sim/paths.py finds them.
import os

from catkin_pkg.python_setup import generate_distutils_setup
from setuptools import find_packages, setup

HERE = os.path.dirname(os.path.abspath(__file__))
ROOTS = ('anafi_sim', 'anafi_control')

setup(**generate_distutils_setup(
    packages=sorted(find_packages(HERE, include=[p for r in ROOTS for p in (r, r + '.*')])),
    package_dir={'': '.'},
))

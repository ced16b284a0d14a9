# Used by catkin_python_setup() only (devel space: relays to this tree; `catkin_make install`: copies the
# packages to <install>/lib/python3/dist-packages); do not run directly.
# Every Python package below the three roots is shipped: anafi_sim with its stage subpackages
# (sim, telemetry, interface, gazebo, mission, ros), anafi_control and anafi_lab (engine, calibration,
# fidelity, reports, cli). Data files
# (anafi_sim/{config,data,launch,urdf}) are not Python packages: CMakeLists.txt installs them under
# share/anafi_sim/anafi_sim, where anafi_sim/paths.py finds them.
import os

from catkin_pkg.python_setup import generate_distutils_setup
from setuptools import find_packages, setup

HERE = os.path.dirname(os.path.abspath(__file__))
ROOTS = ('anafi_sim', 'anafi_control', 'anafi_lab')

setup(**generate_distutils_setup(
    packages=sorted(find_packages(HERE, include=[p for r in ROOTS for p in (r, r + '.*')])),
    package_dir={'': '.'},
    # the lab's sweep specs, the report templates and the fidelity room's data files (installed with the package)
    package_data={'anafi_lab': ['sweeps/*.yaml'],
                  'anafi_lab.reports': ['templates/*.md', 'templates/*.yaml', 'templates/*/*.md'],
                  'anafi_lab.fidelity': ['*.yaml']},
))

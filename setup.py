# Used by catkin_python_setup() only; do not run directly.
from setuptools import setup
from catkin_pkg.python_setup import generate_distutils_setup

setup(**generate_distutils_setup(
    packages=['anafi_sim', 'anafi_sim.sim', 'anafi_sim.telemetry', 'anafi_sim.interface', 'anafi_sim.gazebo',
              'anafi_sim.experiments', 'anafi_sim.calibration', 'anafi_sim.ros', 'anafi_control'],
    package_dir={'': '.'},
))

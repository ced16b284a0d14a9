"""anafi_control: the control library (controller contract, frames, PID framework, MPCs; no ROS, no anafi_sim).

The paper authors' ROS message package is also called ``anafi_control`` (README, "The anafi_control name
clash"). Extending the package path lets their ``anafi_control.msg`` be found behind this package when this
one comes first on sys.path; when theirs comes first, ``import anafi_sim`` stops with a clear message.
"""
__path__ = __import__('pkgutil').extend_path(__path__, __name__)

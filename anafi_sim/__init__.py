"""anafi_sim: simulated Anafi, Sphinx ground-truth interface and Gazebo mirror (pure cores).

The generated messages (``anafi_sim.msg``) live in the catkin devel/install
space; extend the package path so they are found whichever copy of this
package comes first on sys.path (e.g. pytest run from the source tree).
"""
__path__ = __import__('pkgutil').extend_path(__path__, __name__)

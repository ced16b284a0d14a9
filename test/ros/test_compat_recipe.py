#!/usr/bin/env python3
"""rostest (compat_recipe.test): docs/compat.md's recipe, followed literally in a shell, starts their launch files.

The bash block of docs/compat.md's first section is read from the file and run line by line in a new bash
(HOME, LANG and a system PATH only: nothing sourced) in the checkout, with its placeholders filled:

- THEIR_WS: a workspace standing in for the paper authors' (their packages are not on this machine), built
  here with catkin_make in a temporary folder: the package sphinx_with_gazebo (the name of their launch
  package) with launch/stand_in.launch, whose node (their_node.py) prints one line when it hears
  /anafi/position_control/state_enu (their MPC's input, from their bridge fork);
- the optional arguments ``[...]`` of compat.launch: ``telemetry_port:=0`` (Sphinx's 9060 may be taken by
  another simulator on this machine: compat.launch then serves on a free port);
- THEIR_PACKAGE THEIR_LAUNCH_FILE: sphinx_with_gazebo stand_in.launch.

The lines before the first roslaunch are the shell's set-up; each roslaunch line then runs in a shell of its own
with that set-up, as in two terminals beside a roscore: compat.launch first, then their launch file.
Checks: the block has exactly these placeholders and two roslaunch lines; after the set-up, their package is found
(``rospack find sphinx_with_gazebo``: the ``--extend`` keeps their workspace) and ``tlm-data-logger`` is our
stand-in from the package's libexec folder; compat.launch starts the simulated Anafi; their launch file starts
and its node hears state_enu. Every process is stopped by its id; ROS_HOME, ROS_LOG_DIR and a free port
(ROS_MASTER_URI) are the test's own.
"""
import os
import re
import shutil
import subprocess
import tempfile
import unittest

import rostest

from anafi_sim import processes

ROOT = os.path.realpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..'))
DOC = os.path.join(ROOT, 'docs', 'compat.md')
SYSTEM_PATH = '/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin'
THEIR_PACKAGE = 'sphinx_with_gazebo'
THEIR_LAUNCH = 'stand_in.launch'
HEARD = 'their_node: heard position_control/state_enu'
TIMEOUT = 180.0   # s wall at most for each launch to come up (a loaded machine)

PACKAGE_XML = '''<?xml version="1.0"?>
<package format="2">
  <name>%s</name>
  <version>0.0.0</version>
  <description>Stand-in for the paper authors' launch package (compat_recipe.test).</description>
  <maintainer email="test@example.com">test</maintainer>
  <license>MIT</license>
  <buildtool_depend>catkin</buildtool_depend>
  <exec_depend>rospy</exec_depend>
</package>
''' % THEIR_PACKAGE
CMAKELISTS = '''cmake_minimum_required(VERSION 3.0.2)
project(%s)
find_package(catkin REQUIRED)
catkin_package()
''' % THEIR_PACKAGE
LAUNCH = '''<launch>
  <node pkg="%s" type="their_node.py" name="their_node" ns="anafi" output="screen"/>
</launch>
''' % THEIR_PACKAGE
NODE = '''#!/usr/bin/env python3
import rospy
rospy.init_node('their_node')
rospy.wait_for_message('/anafi/position_control/state_enu', rospy.AnyMsg)
print('%s', flush=True)
rospy.spin()
''' % HEARD


def recipe():
    """The lines of the first bash block of docs/compat.md."""
    with open(DOC) as f:
        text = f.read()
    block = re.search(r'```bash\n(.*?)```', text, re.S)
    return [line for line in block.group(1).splitlines() if line.strip()]


def their_workspace(base):
    """A catkin workspace with the stand-in package, built: its root."""
    ws = os.path.join(base, 'their_ws')
    pkg = os.path.join(ws, 'src', THEIR_PACKAGE)
    os.makedirs(os.path.join(pkg, 'launch'))
    os.makedirs(os.path.join(pkg, 'scripts'))
    for path, text in (('package.xml', PACKAGE_XML), ('CMakeLists.txt', CMAKELISTS),
                       (os.path.join('launch', THEIR_LAUNCH), LAUNCH), (os.path.join('scripts', 'their_node.py'), NODE)):
        with open(os.path.join(pkg, path), 'w') as f:
            f.write(text)
    os.chmod(os.path.join(pkg, 'scripts', 'their_node.py'), 0o755)
    out = subprocess.run(['bash', '-c', 'catkin_make'], cwd=ws, env=clean_env(base), stdin=subprocess.DEVNULL,
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True, timeout=300.0)
    assert out.returncode == 0, out.stdout[-3000:]
    return ws


def clean_env(base, **extra):
    """A new shell's environment: HOME, LANG, the system PATH; ROS's home and logs under ``base``."""
    env = dict((k, os.environ[k]) for k in ('HOME', 'LANG') if k in os.environ)
    env.update(PATH=SYSTEM_PATH, ROS_HOME=os.path.join(base, 'ros_home'), ROS_LOG_DIR=os.path.join(base, 'log'),
               PYTHONUNBUFFERED='1')     # the output read while it runs
    env.update(extra)
    return env


def contains(path, text):
    try:
        with open(path) as f:
            return text in f.read()
    except IOError:
        return False


class TestCompatRecipe(unittest.TestCase):
    def test_the_recipe_starts_their_launch_files(self):
        lines = recipe()
        launches = [i for i, line in enumerate(lines) if line.startswith('roslaunch ')]
        self.assertEqual(len(launches), 2, lines)
        setup, (ours, theirs) = lines[:launches[0]], [lines[i] for i in launches]
        self.assertTrue(any('THEIR_WS' in line for line in setup), setup)
        self.assertIn('THEIR_PACKAGE THEIR_LAUNCH_FILE', theirs)
        self.assertIn('compat.launch [', ours)

        base = tempfile.mkdtemp(prefix='compat_recipe_')
        procs = processes.Processes(base, grace=20.0)
        try:
            ws = their_workspace(base)
            setup = ['cd "%s"' % ROOT] + [line.replace('THEIR_WS', ws) for line in setup]
            ours = re.sub(r'(\s*\[[^]]*\])+', ' telemetry_port:=0', ours)
            theirs = theirs.replace('THEIR_PACKAGE THEIR_LAUNCH_FILE', '%s %s' % (THEIR_PACKAGE, THEIR_LAUNCH))
            env = clean_env(base)
            # the user's roscore (roslaunch would start one, but may give up on it on a loaded machine)
            processes.start_master(procs, env)

            # the set-up alone: their package found, our tlm-data-logger from the libexec folder
            probe = subprocess.run(['bash', '-c', '\n'.join(setup + ['rospack find %s' % THEIR_PACKAGE,
                                                                       'command -v tlm-data-logger'])],
                                   env=env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                   stderr=subprocess.STDOUT, universal_newlines=True, timeout=120.0)
            self.assertEqual(probe.returncode, 0, probe.stdout)
            found = probe.stdout.split()
            self.assertIn(os.path.join(ws, 'src', THEIR_PACKAGE), found, probe.stdout)
            self.assertTrue(found[-1].endswith('/anafi_sim/tlm-data-logger'), probe.stdout)

            for name, line, ready in (('compat', ours, 'anafi_sim: drone anafi'), ('theirs', theirs, HEARD)):
                proc = procs.start(name, ['bash', '-c', '\n'.join(setup + [line])], env)
                log = procs.log_path(name)
                up = processes.wait_for(lambda: contains(log, ready) or proc.poll() is not None, TIMEOUT, step=0.5)
                with open(log) as f:
                    text = f.read()
                self.assertTrue(up and ready in text, '%s: no "%s" (%s):\n%s' % (line, ready, log, text[-3000:]))
                self.assertIsNone(proc.poll(), text[-3000:])
            self.assertFalse(contains(procs.log_path('theirs'), 'neither a launch file'))
        finally:
            procs.stop_all()
        shutil.rmtree(base, ignore_errors=True)


if __name__ == '__main__':
    rostest.rosrun('anafi_sim', 'test_compat_recipe', TestCompatRecipe)

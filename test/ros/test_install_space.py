#!/usr/bin/env python3
"""rostest: the package built into install spaces works from them alone (see install_space.test).

The checkout is copied into a temporary catkin workspace and built twice, in a clean environment (no devel
space, no ROS variables; only Noetic's /opt/ros/noetic/setup.bash where ROS lives there), with the
interpreter this test runs on (the venv with osqp) as PYTHON_EXECUTABLE and testing off:
``catkin_make install`` (merged install space) and ``catkin_make_isolated --install`` (per-package layout,
as catkin build / catkin_make_isolated install). Each install space's setup.bash is then the only thing
sourced:

1. environment: ROS_PACKAGE_PATH, PYTHONPATH, CMAKE_PREFIX_PATH, PATH and Python's sys.path name no part of
   the devel space or of the checkout; rospack, ``import anafi_sim`` / ``anafi_control``, the generated
   messages and dynamic_reconfigure modules and anafi_sim.paths (the data files, the shipped reference
   logs) all point into the install space;
2. contents: every Python package of the checkout (anafi_sim.*, with the nodes, anafi_control) and every script of
   anafi_sim/scripts is installed; the scripts run on PYTHON_EXECUTABLE (which imports osqp);
3. every launch file loads there as roslaunch loads it (includes, $(find) paths, rosparam files) and
   every node's pkg/type is found in the install space's lib/anafi_sim; sim.launch's telemetry command
   is the installed tlm_data_logger.py;
4. ``rosrun anafi_sim evaluate_log.py --help`` exits 0;
5. (merged install space) ``roslaunch anafi_sim sim.launch`` + ``roslaunch anafi_sim mpc.launch`` on a
   private master: ground truth (/anafi/ground_truth/odom) is published, and once a waypoint is
   published the MPC sends piloting commands (/anafi/drone/rpyt, solved cycles on /anafi/mpc/stats)
   that fly the drone towards it. A probe script run with the install space's environment publishes the
   waypoint and watches the topics.

Everything (workspace, build, HOME, ROS logs) lives in one temporary folder, removed at the end (kept when
ANAFI_SIM_KEEP_TMP is set).
"""
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
import unittest

import rostest
from setuptools import find_packages

from anafi_sim import processes

PKG = 'anafi_sim'
ROOT = os.path.realpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..'))
PYTHON = sys.executable                  # the workspace's interpreter (the venv with osqp under env.bash)
UNDERLAY = '/opt/ros/noetic/setup.bash'  # Ubuntu's ROS; Debian's ROS lives in /usr and needs no sourcing
SYSTEM_PATH = '/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin'
PY_ROOTS = ('anafi_sim', 'anafi_control')
SPACES = ('install', 'install_isolated')
BUILD_TIMEOUT = 240.0   # s per build (about 10 s on 2 cores)
GT_TIMEOUT = 40.0       # s from the launch until ground truth flows with the drone in the air
WP_TIMEOUT = 20.0       # s from the first waypoint until commands moved the drone towards it

PROBE = r'''
import json, sys, threading, time
import rospy
from nav_msgs.msg import Odometry
from anafi_sim.msg import MpcStats, Waypoint

NS = '/anafi'
GT_TIMEOUT, WP_TIMEOUT = float(sys.argv[1]), float(sys.argv[2])
lock = threading.Lock()
st = {'odom': 0, 'pos': None, 'cmd': [], 'cmd_type': None, 'solved': []}

def on_odom(m):
    p = m.pose.pose.position
    with lock:
        st['odom'] += 1
        st['pos'] = (p.x, p.y, p.z)

def on_cmd(m):
    with lock:
        st['cmd'].append(time.time())
        st['cmd_type'] = m._connection_header.get('type')

def on_stats(m):
    if m.ok:
        with lock:
            st['solved'].append(time.time())

def wait(pred, timeout):
    end = time.time() + timeout
    while time.time() < end and not rospy.is_shutdown():
        with lock:
            if pred():
                return True
        time.sleep(0.05)
    with lock:
        return pred()

rospy.init_node('install_space_probe', disable_signals=True)
rospy.Subscriber(NS + '/ground_truth/odom', Odometry, on_odom, queue_size=100)
rospy.Subscriber(NS + '/drone/rpyt', rospy.AnyMsg, on_cmd, queue_size=100)
rospy.Subscriber(NS + '/mpc/stats', MpcStats, on_stats, queue_size=100)
pub = rospy.Publisher(NS + '/position_control/waypoint', Waypoint, queue_size=1)
out = {}
t0 = time.time()
out['ground_truth'] = wait(lambda: st['odom'] >= 100 and st['pos'][2] > 0.8, GT_TIMEOUT)
out['ground_truth_after'] = round(time.time() - t0, 1)
with lock:
    out['odom_count'], start = st['odom'], st['pos']
if out['ground_truth']:
    goal = (start[0] + 0.5, start[1], start[2] + 1.0)
    out['start'], out['goal'] = start, goal
    t_wp = time.time()
    stop = threading.Event()

    def publish():
        while not stop.is_set():
            wp = Waypoint(x=goal[0], y=goal[1], z=goal[2])
            wp.header.stamp = rospy.Time.now()
            wp.header.frame_id = 'world'
            pub.publish(wp)
            stop.wait(0.1)
    threading.Thread(target=publish, daemon=True).start()
    moved = lambda: st['pos'][2] > start[2] + 0.5
    out['moved'] = wait(lambda: moved() and sum(t > t_wp for t in st['solved']) >= 5, WP_TIMEOUT)
    stop.set()
    with lock:
        out['commands_after_waypoint'] = sum(t > t_wp for t in st['cmd'])
        out['solved_after_waypoint'] = sum(t > t_wp for t in st['solved'])
        out['command_type'] = st['cmd_type']
        out['end'] = st['pos']
    out['moved_after'] = round(time.time() - t_wp, 1)
print('PROBE ' + json.dumps(out))
sys.stdout.flush()
rospy.signal_shutdown('done')
'''

# Loads launch files (argv[2:], of package argv[1]) as roslaunch does, without running them; prints JSON
# {file: {params: count, nodes: [[pkg, type, executable found]], telemetry_command} or {error | missing}}.
RESOLVE = r'''
import json, os, sys
import rospkg, roslaunch.config, roslib.packages
out = {}
share = rospkg.RosPack().get_path(sys.argv[1])
# the arguments a launch file requires (no default, by design: real_anafi.launch's fence, controller.launch's controller)
required = {'real_anafi.launch': ['fence_radius:=10.0', 'fence_min_altitude:=0.5', 'fence_max_altitude:=8.0'],
            'controller.launch': ['controller:=mpc']}
for name in sys.argv[2:]:
    try:
        config = roslaunch.config.load_config_default(
            [(os.path.join(share, sys.argv[1], 'launch', name), required.get(name, []))], None)
    except rospkg.ResourceNotFound as exc:
        out[name] = {'missing': str(exc.args[0]) if exc.args else str(exc)}
        continue
    except Exception as exc:
        out[name] = {'error': '%s: %s' % (type(exc).__name__, exc)}
        continue
    nodes = []
    for n in config.nodes:
        found = roslib.packages.find_node(n.package, n.type)
        nodes.append([n.package, n.type, found[0] if found else None])
    command = config.params.get('/anafi/interface/telemetry_command')
    out[name] = {'params': len(config.params), 'nodes': nodes,
                 'telemetry_command': command.value if command else None}
print(json.dumps(out))
'''


def under(path, root):
    path, root = os.path.realpath(path), os.path.realpath(root)
    return path == root or path.startswith(root.rstrip('/') + '/')


def tail(path, n=30):
    try:
        with open(path, 'rb') as f:
            return b''.join(f.readlines()[-n:]).decode('utf-8', 'replace')
    except IOError:
        return '(no %s)' % path


def copy_ignore(directory, names):
    """What not to copy into the temporary workspace: hidden entries (.git, .ws, .venv ...), results, caches."""
    skip = set(n for n in names if n in ('__pycache__', '.pytest_cache') or n.endswith('.pyc'))
    if os.path.realpath(directory) == ROOT:
        skip |= set(n for n in names if n.startswith('.') or n in ('test_results', 'run', 'env.bash'))
    return skip


def devel_roots():
    """Folders an install-space environment must not refer to: the checkout and this environment's own
    workspace entries (the devel space), except the venv whose python runs everything."""
    roots = {ROOT}
    for var in ('CMAKE_PREFIX_PATH', 'ROS_PACKAGE_PATH'):
        for entry in os.environ.get(var, '').split(os.pathsep):
            if entry and not entry.startswith(('/usr', '/opt/ros')):
                roots.add(os.path.realpath(entry))
    return roots


class InstallSpaceTest(unittest.TestCase):
    tmp = None
    envs = {}

    @classmethod
    def setUpClass(cls):
        cls.t_start = time.time()
        cls.tmp = os.path.realpath(tempfile.mkdtemp(prefix='anafi_install_'))
        cls.home = os.path.join(cls.tmp, 'home')
        cls.ws = os.path.join(cls.tmp, 'ws')
        cls.logs = os.path.join(cls.tmp, 'logs')
        for d in (cls.home, cls.logs):
            os.makedirs(d)
        shutil.copytree(ROOT, os.path.join(cls.ws, 'src', PKG), ignore=copy_ignore)
        cls.base_env = {'HOME': cls.home, 'PATH': SYSTEM_PATH, 'LANG': 'C.UTF-8', 'TMPDIR': cls.tmp,
                        'ROS_HOME': os.path.join(cls.home, '.ros'), 'ROS_LOG_DIR': cls.logs,
                        'MPLCONFIGDIR': os.path.join(cls.home, 'mpl'), 'PYTHONUNBUFFERED': '1'}
        cmake_args = '-DPYTHON_EXECUTABLE=%s -DCATKIN_ENABLE_TESTING=OFF -j2' % PYTHON
        builds = {'install': 'catkin_make install ' + cmake_args,
                  'install_isolated': 'catkin_make_isolated --install ' + cmake_args}
        cls.build_times = {}
        for space in SPACES:
            t0 = time.time()
            log = os.path.join(cls.logs, 'build_%s.log' % space)
            with open(log, 'wb') as out:
                rc = subprocess.call(['bash', '-c', cls.underlay() + 'cd "%s" && %s' % (cls.ws, builds[space])],
                                     env=cls.base_env, stdin=subprocess.DEVNULL, stdout=out,
                                     stderr=subprocess.STDOUT, timeout=BUILD_TIMEOUT)
            cls.build_times[space] = time.time() - t0
            if rc != 0:
                raise AssertionError('%s failed (exit %d):\n%s' % (builds[space], rc, tail(log)))
            cls.envs[space] = cls.sourced(os.path.join(cls.ws, space, 'setup.bash'))
        print('install_space: builds %s' % ', '.join('%s %.0f s' % kv for kv in sorted(cls.build_times.items())))

    @classmethod
    def tearDownClass(cls):
        if cls.tmp and not os.environ.get('ANAFI_SIM_KEEP_TMP'):
            shutil.rmtree(cls.tmp, ignore_errors=True)
        elif cls.tmp:
            print('install_space: kept %s' % cls.tmp)
        print('install_space: %.0f s in all' % (time.time() - cls.t_start))

    @staticmethod
    def underlay():
        return 'source "%s" && ' % UNDERLAY if os.path.isfile(UNDERLAY) else ''

    @classmethod
    def sourced(cls, setup):
        """The environment of the clean base environment after sourcing ``setup`` (and nothing else)."""
        out = subprocess.check_output(['bash', '-c', cls.underlay() + 'source "%s" && env -0' % setup],
                                      env=cls.base_env, stdin=subprocess.DEVNULL, timeout=60)
        return dict(item.split('=', 1) for item in out.decode().split('\0') if '=' in item)

    def run_in(self, space, argv, timeout=60.0, **kw):
        return subprocess.run(argv, env=self.envs[space], cwd=self.tmp, stdin=subprocess.DEVNULL,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=timeout, **kw)

    # ------------------------------------------------------------------------------------------ checks
    def test_0_environment_is_the_install_space_only(self):
        roots = devel_roots()
        venv = os.path.realpath(sys.prefix)
        for space in SPACES:
            prefix = os.path.join(self.ws, space)
            env = self.envs[space]
            entries = []
            for var in ('ROS_PACKAGE_PATH', 'PYTHONPATH', 'CMAKE_PREFIX_PATH', 'PATH', 'LD_LIBRARY_PATH',
                        'PKG_CONFIG_PATH'):
                entries += [(var, e) for e in env.get(var, '').split(os.pathsep) if e]
            self.assertIn((('CMAKE_PREFIX_PATH', prefix)), entries)
            code = ('import json, sys, rospkg, anafi_sim, anafi_control, anafi_sim.msg, anafi_sim.cfg.MpcConfig, '
                    'anafi_sim.cfg.PidConfig\nfrom anafi_sim import paths\n'
                    'print(json.dumps({"sys.path": sys.path, "rospack": rospkg.RosPack().get_path("anafi_sim"), '
                    '"anafi_sim": anafi_sim.__file__, "anafi_control": anafi_control.__file__, '
                    '"msg": anafi_sim.msg.__file__, "cfg": anafi_sim.cfg.MpcConfig.__file__, '
                    '"package_dir": paths.package_dir(), "mpc.yaml": paths.config_path("mpc.yaml"), '
                    '"reference_logs": paths.reference_logs_dir()}))')
            r = self.run_in(space, [PYTHON, '-c', code])
            self.assertEqual(r.returncode, 0, r.stderr.decode())
            found = json.loads(r.stdout.decode())
            entries += [('sys.path', e) for e in found.pop('sys.path') if e]
            leaks = [(var, e) for var, e in entries
                     if any(under(e, root) for root in roots) and not under(e, venv)]
            self.assertEqual(leaks, [], '%s: devel space / checkout in the environment' % space)
            for what, path in sorted(found.items()):
                self.assertTrue(under(path, prefix), '%s: %s is %s, not in %s' % (space, what, path, prefix))
            self.assertTrue(os.path.isfile(found['mpc.yaml']), found['mpc.yaml'])
            for sub in ('', 'real'):      # the shipped reference logs, as in the source tree
                logs = os.path.join(found['reference_logs'], sub)
                self.assertEqual(sorted(n for n in os.listdir(logs) if n.endswith('.csv')),
                                 sorted(n for n in os.listdir(os.path.join(ROOT, PKG, 'data', 'reference_logs', sub))
                                        if n.endswith('.csv')), logs)

    def test_1_packages_and_scripts_installed(self):
        packages = sorted(find_packages(ROOT, include=[p for r in PY_ROOTS for p in (r, r + '.*')]))
        self.assertIn('anafi_sim.sim', packages)
        self.assertIn('anafi_sim.nodes', packages)     # the nodes' classes, which the scripts' mains import
        node_modules = sorted(n for n in os.listdir(os.path.join(ROOT, PKG, 'nodes')) if n.endswith('.py'))
        scripts = sorted(n for n in os.listdir(os.path.join(ROOT, PKG, 'scripts')) if n.endswith('.py'))
        scripts.append('tlm-data-logger')      # the telemetry stand-in under Sphinx's name (compat.launch)
        r = subprocess.run([PYTHON, '-c', 'import osqp'], stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
        self.assertEqual(r.returncode, 0, '%s cannot import osqp: %s' % (PYTHON, r.stdout.decode()))
        for space in SPACES:
            prefix = os.path.join(self.ws, space)
            site = os.path.join(prefix, 'lib', 'python3', 'dist-packages')
            missing = [p for p in packages
                       if not os.path.isfile(os.path.join(site, *p.split('.') + ['__init__.py']))]
            self.assertEqual(missing, [], '%s: Python packages not installed' % space)
            missing = [n for n in node_modules if not os.path.isfile(os.path.join(site, PKG, 'nodes', n))]
            self.assertEqual(missing, [], '%s: node modules not installed' % space)
            bin_dir = os.path.join(prefix, 'lib', PKG)
            for name in scripts:
                path = os.path.join(bin_dir, name)
                self.assertTrue(os.access(path, os.X_OK), '%s: %s not installed as a program' % (space, path))
                with open(path) as f:
                    shebang = f.readline().strip()
                self.assertEqual(shebang, '#!' + PYTHON, '%s: %s runs on another interpreter' % (space, path))

    def test_2_launch_files_resolve(self):
        launches = sorted(n for n in os.listdir(os.path.join(ROOT, PKG, 'launch')) if n.endswith('.launch'))
        for space in SPACES:
            prefix = os.path.join(self.ws, space)
            r = self.run_in(space, [PYTHON, '-c', RESOLVE, PKG] + launches)
            self.assertEqual(r.returncode, 0, r.stderr.decode())
            resolved = json.loads(r.stdout.decode().splitlines()[-1])
            for name in launches:
                got = resolved[name]
                if name == 'sphinx_gazebo.launch' and got.get('missing') == 'gazebo_ros':
                    continue   # includes gazebo_ros's empty_world.launch: checked where Gazebo is installed
                self.assertNotIn('error', got, '%s: %s' % (space, name))
                self.assertTrue(got['params'] > 0 and got['nodes'], '%s: %s: %s' % (space, name, got))
                for pkg, node_type, path in got['nodes']:
                    self.assertTrue(path and (pkg != PKG or under(path, prefix)),
                                    '%s: %s: node %s/%s found at %s' % (space, name, pkg, node_type, path))
                if name == 'sim.launch':
                    command = got['telemetry_command'].split()
                    self.assertEqual(command[0], os.path.join(prefix, 'lib', PKG, 'tlm_data_logger.py'))

    def test_3_rosrun_evaluate_log_help(self):
        for space in SPACES:
            if not shutil.which('rosrun', path=self.envs[space]['PATH']):
                self.fail('rosrun not found (Debian package rosbash; make setup installs it)')
            r = self.run_in(space, ['rosrun', PKG, 'evaluate_log.py', '--help'])
            self.assertEqual(r.returncode, 0, '%s: %s%s' % (space, r.stdout.decode(), r.stderr.decode()))
            self.assertIn('usage: evaluate_log.py', r.stdout.decode())

    def test_4_sim_and_mpc_run_from_the_install_space(self):
        t0 = time.time()
        env = dict(self.envs['install'])
        procs = processes.Processes(self.logs)
        try:
            processes.start_master(procs, env)
            procs.start('sim', ['roslaunch', PKG, 'sim.launch', 'telemetry_port:=0'], env)
            procs.start('mpc', ['roslaunch', PKG, 'mpc.launch'], env)
            probe = os.path.join(self.tmp, 'probe.py')
            with open(probe, 'w') as f:
                f.write(PROBE)
            r = subprocess.run([PYTHON, probe, str(GT_TIMEOUT), str(WP_TIMEOUT)], env=env, cwd=self.tmp,
                               stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                               timeout=GT_TIMEOUT + WP_TIMEOUT + 30)
            out = r.stdout.decode('utf-8', 'replace')
            lines = [l for l in out.splitlines() if l.startswith('PROBE ')]
            logs = '\n'.join('--- %s\n%s' % (n, procs.log_tail(n)) for n in ('sim', 'mpc'))
            self.assertTrue(lines, 'probe gave no result (exit %d):\n%s\n%s' % (r.returncode, out, logs))
            result = json.loads(lines[-1][len('PROBE '):])
            print('install_space: launch check %s (%.0f s)' % (json.dumps(result), time.time() - t0))
            self.assertTrue(result['ground_truth'], 'no ground truth: %s\n%s' % (result, logs))
            self.assertTrue(result['moved'], 'the MPC did not fly to the waypoint: %s\n%s' % (result, logs))
            self.assertGreaterEqual(result['commands_after_waypoint'], 5, result)
            self.assertEqual(result['command_type'], 'olympe_bridge/PilotingCommand', result)
        finally:
            left = procs.stop_all()
        self.assertEqual(left, [], 'processes left running')


if __name__ == '__main__':
    rostest.rosrun(PKG, 'install_space', InstallSpaceTest)

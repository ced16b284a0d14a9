#!/usr/bin/env python3
"""rviz of a fleet under Xvfb (fleet_rviz.test): `roslaunch anafi_sim fleet.launch drones:=3 rviz:=true` shows
all three drones.

The test starts Xvfb (as test_rviz.py does: -displayfd, the screen read from -fbdir's XWD file), then the
fleet launch itself with DISPLAY set and software GL (so the launch's own rviz, on the view fleet_launcher.py
generated into out_dir/fleet.rviz, is what is seen). Every 3 s it reads the screen and each drone's ground
truth, and projects each drone's position into the 3D view with the generated view's camera
(anafi_sim.mission.rviz_config.project). Asserts, within 300 s: each drone's dark model pixels around
its projected position (the three drones are found where they fly, all inside the view), each drone's
markers on /<drone>/visualisation/markers, and the trail colour in the view. The screenshot goes to
test_results/fleet_rviz.png (ANAFI_FLEET_RVIZ_SCREENSHOT=PATH: there too; ANAFI_FLEET_RVIZ_HOLD=S: taken S s
after the checks passed, e.g. docs/fleet_rviz.png with the circles under way). Skipped where rviz or Xvfb is
not installed.
"""
import os
import shutil
import sys
import tempfile
import threading
import time
import unittest

import numpy as np
import rospy
import rostest
import yaml
from nav_msgs.msg import Odometry
from visualization_msgs.msg import MarkerArray

from anafi_sim import paths
from anafi_sim.mission.rviz_config import project
from anafi_sim.mission.visualisation import COLOURS
from anafi_sim.processes import start, stop

from test_rviz import colour_mask, read_xwd, start_xvfb  # beside this script (a script's folder is on its path)

NAMES = ('anafi1', 'anafi2', 'anafi3')
WINDOW = 30          # px around a drone's projected position searched for its model
MIN_DARK = 6         # dark pixels of one drone's model at the fleet view's distance
MIN_TRAIL = 100      # trail-coloured pixels in the view (three trails)
DEADLINE = 300.0     # s: three drones' graphs + rviz under software GL on a loaded machine


def generated_view(path):
    """The Orbit view of a generated fleet.rviz as rviz_config.project takes it."""
    with open(path) as f:
        view = yaml.safe_load(f)['Visualization Manager']['Views']['Current']
    return {'focal': tuple(float(view['Focal Point'][k]) for k in 'XYZ'), 'distance': float(view['Distance']),
            'yaw': float(view['Yaw']), 'pitch': float(view['Pitch'])}, yaml.safe_load(open(path))


def background(config):
    return tuple(int(v) for v in config['Visualization Manager']['Global Options']['Background Color'].split(';'))


def view_box(image, colour):
    """(row0, row1, col0, col1) of the 3D view: the bounding box of the background colour, or None."""
    rows, cols = np.nonzero(np.all(image == np.array(colour), axis=2))
    if len(rows) < 10000:
        return None
    return rows.min(), rows.max() + 1, cols.min(), cols.max() + 1


class TestFleetRviz(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        cls.procs = []
        cls.tmp = tempfile.mkdtemp(prefix='fleet_rviz_test_')
        rospy.init_node('test_fleet_rviz')
        cls.lock = threading.Lock()
        cls.truth, cls.marker_kinds = {}, dict((n, set()) for n in NAMES)
        for name in NAMES:
            rospy.Subscriber('/%s/ground_truth/odom' % name, Odometry, cls.on_truth, callback_args=name,
                             queue_size=2)
            rospy.Subscriber('/%s/visualisation/markers' % name, MarkerArray, cls.on_markers, callback_args=name,
                             queue_size=2)

    @classmethod
    def on_truth(cls, msg, name):
        p = msg.pose.pose.position
        with cls.lock:
            cls.truth[name] = (p.x, p.y, p.z)

    @classmethod
    def on_markers(cls, msg, name):
        with cls.lock:
            cls.marker_kinds[name].update(m.ns for m in msg.markers)

    @classmethod
    def tearDownClass(cls):
        for p in reversed(cls.procs):
            stop(p, grace=20.0)
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def start_xvfb(self):
        return start_xvfb(self.tmp, self.procs)

    def found(self, image, view, colour):
        """{drone: (projected (col, row) in the screen or None, dark pixels around it)} and the view box."""
        box = view_box(image, colour)
        out = {}
        if box is None:
            return out, None
        r0, r1, c0, c1 = box
        dark = np.all(image < 70, axis=2)
        with self.lock:
            truth = dict(self.truth)
        for name in NAMES:
            if name not in truth:
                out[name] = (None, 0)
                continue
            pixel = project(view, truth[name], (c1 - c0, r1 - r0))
            if pixel is None:
                out[name] = (None, 0)
                continue
            col, row = int(round(c0 + pixel[0])), int(round(r0 + pixel[1]))
            if not (c0 <= col < c1 and r0 <= row < r1):
                out[name] = ((col, row), 0)
                continue
            window = dark[max(r0, row - WINDOW):min(r1, row + WINDOW + 1),
                          max(c0, col - WINDOW):min(c1, col + WINDOW + 1)]
            out[name] = ((col, row), int(window.sum()))
        return out, box

    def test_screenshot_finds_every_drone(self):
        for tool in ('rviz', 'Xvfb'):
            if shutil.which(tool) is None:
                self.skipTest('%s is not installed (tools/setup.sh installs rviz and xvfb)' % tool)
        display, screen = self.start_xvfb()
        out_dir = os.path.join(self.tmp, 'fleet')
        env = dict(os.environ, DISPLAY=display, LIBGL_ALWAYS_SOFTWARE='1')
        env.pop('WAYLAND_DISPLAY', None)
        log = os.path.join(self.tmp, 'fleet.log')
        self.procs.append(start(['roslaunch', 'anafi_sim', 'fleet.launch', 'drones:=3', 'rviz:=true',
                                 'evaluate:=false', 'out_dir:=' + out_dir], env=env, log=log))
        rviz_file = os.path.join(out_dir, 'fleet.rviz')
        image, found, box, trail = None, {}, None, 0
        deadline = time.time() + DEADLINE
        view = config = None
        while time.time() < deadline:
            time.sleep(3.0)
            self.assertIsNone(self.procs[-1].poll(), 'the fleet launch ended; log: %s' % open(log).read()[-3000:])
            if view is None:
                if not os.path.isfile(rviz_file):
                    continue
                view, config = generated_view(rviz_file)
            image = read_xwd(screen)
            found, box = self.found(image, view, background(config))
            if box is None:
                continue
            trail = int(colour_mask(image[box[0]:box[1], box[2]:box[3]], COLOURS['trail']).sum())
            if all(found.get(n, (None, 0))[1] >= MIN_DARK for n in NAMES) and trail >= MIN_TRAIL:
                break
        hold = float(os.environ.get('ANAFI_FLEET_RVIZ_HOLD', '0'))     # s more of flight for a documentation shot
        if hold > 0.0 and image is not None:
            time.sleep(hold)
            image = read_xwd(screen)
        if image is not None:
            self.save(image)
        print('view box %s; per drone (projected pixel, dark pixels around it): %s; trail pixels %d; markers %s'
              % (box, found, trail, self.marker_kinds))
        self.assertIsNotNone(view, 'fleet_launcher.py wrote no %s' % rviz_file)
        self.assertIsNotNone(box, 'no 3D view (background of %s) on the screen' % rviz_file)
        for name in NAMES:
            pixel, dark = found.get(name, (None, 0))
            self.assertIsNotNone(pixel, '%s: no ground truth, or behind the camera' % name)
            self.assertGreaterEqual(dark, MIN_DARK, '%s: %d dark (model) pixels around %s (view %s)'
                                    % (name, dark, pixel, box))
            self.assertTrue(any(ns.startswith(name + '/') for ns in self.marker_kinds[name]),
                            '%s: no markers on /%s/visualisation/markers' % (name, name))
        self.assertGreaterEqual(trail, MIN_TRAIL, 'trail colour: %d pixels' % trail)

    def save(self, image):
        import matplotlib
        matplotlib.use('Agg')
        import matplotlib.image
        targets = [os.path.join(paths.package_dir(), 'test_results', 'fleet_rviz.png')]
        if os.environ.get('ANAFI_FLEET_RVIZ_SCREENSHOT'):
            targets.append(os.environ['ANAFI_FLEET_RVIZ_SCREENSHOT'])
        for path in targets:
            os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
            matplotlib.image.imsave(path, image)
            print('screenshot: %s' % path)


if __name__ == '__main__':
    rostest.rosrun('anafi_sim', 'test_fleet_rviz', TestFleetRviz, sys.argv)

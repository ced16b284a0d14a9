#!/usr/bin/env python3
"""rviz under Xvfb on a short scenario (rviz.test): the screenshot is not blank and shows the drone and the
paths in their colours (anafi_sim.mission.visualisation.COLOURS, anafi_sim/config/anafi.rviz).

The test starts Xvfb (-displayfd picks a free display; -fbdir keeps the screen in an XWD file, read here: no
screenshot tool needed) and rviz -d anafi.rviz with software GL while the drone takes off for the circle
(circle_r2_v1, restarted whenever it is done), and reads the screen every 2 s until every colour is in
the 3D view (the area of the config's background colour) or 200 s passed. Asserts, in the 3D view: pixels of each marker colour (trail
green, reference blue, predicted magenta, waypoint orange), dark pixels of the drone model, a non-uniform
image; and that visualisation_node.py published every kind of marker. The screenshot goes to test_results/rviz.png (ANAFI_RVIZ_SCREENSHOT=PATH: there
too, e.g. docs/rviz.png). Skipped where rviz or Xvfb is not installed.
"""
import os
import shutil
import struct
import subprocess
import sys
import tempfile
import time
import unittest

import numpy as np
import rospy
import rostest
import yaml
from std_msgs.msg import String
from visualization_msgs.msg import MarkerArray

from anafi_sim import paths
from anafi_sim.mission.visualisation import COLOURS
from anafi_sim.processes import stop, wait_for

DRONE = 'anafi'
SCREEN = (1200, 800)


def rviz_background():
    """anafi.rviz's background colour (R, G, B), 0..255: it marks the 3D view on the screen."""
    with open(paths.config_path('anafi.rviz')) as f:
        text = yaml.safe_load(f)['Visualization Manager']['Global Options']['Background Color']
    return tuple(int(v) for v in text.split(';'))


BACKGROUND = rviz_background()
TOLERANCE = 40        # per channel, 0..255: antialiasing and blending at line edges
#: pixels of each colour needed in the 3D view (the waypoint is a 0.12 m sphere + a thin arrow: 60-200 px)
MIN_PIXELS = {'trail': 100, 'reference': 100, 'predicted': 100, 'waypoint': 40}
MIN_DARK = 30         # pixels of the drone model, in the 3D view


def start_xvfb(tmp, procs):
    """An Xvfb server of ``SCREEN`` writing its frame buffer below ``tmp`` (added to ``procs``): (display,
    path of the frame buffer file)."""
    read_fd, write_fd = os.pipe()
    fbdir = os.path.join(tmp, 'fb')
    os.makedirs(fbdir)
    xvfb = subprocess.Popen(['Xvfb', '-displayfd', str(write_fd), '-fbdir', fbdir, '-screen', '0',
                             '%dx%dx24' % SCREEN, '-nolisten', 'tcp'], pass_fds=(write_fd,),
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    procs.append(xvfb)
    os.close(write_fd)
    with os.fdopen(read_fd) as f:
        display = f.readline().strip()
    if not display:
        raise AssertionError('Xvfb did not report its display')
    return ':' + display, os.path.join(fbdir, 'Xvfb_screen0')


def read_xwd(path):
    """RGB uint8 array (h, w, 3) of an XWD file as Xvfb -fbdir writes it (ZPixmap, 24/32 bits per pixel)."""
    with open(path, 'rb') as f:
        data = f.read()
    header = struct.unpack('>25I', data[:100])
    header_size, version, fmt, depth, width, height = header[:6]
    byte_order, bits_per_pixel, bytes_per_line, ncolors = header[7], header[11], header[12], header[19]
    if version != 7 or fmt != 2 or bits_per_pixel != 32:
        raise ValueError('unsupported XWD: version %d, format %d, %d bpp' % (version, fmt, bits_per_pixel))
    red_mask, green_mask, blue_mask = header[14:17]
    offset = header_size + 12 * ncolors
    raw = np.frombuffer(data, dtype='<u4' if byte_order == 0 else '>u4', count=height * bytes_per_line // 4,
                        offset=offset).reshape(height, bytes_per_line // 4)[:, :width]

    def channel(mask):
        shift = (mask & -mask).bit_length() - 1
        return ((raw & mask) >> shift).astype(np.uint8)
    return np.dstack([channel(red_mask), channel(green_mask), channel(blue_mask)])


def colour_mask(image, rgba):
    target = np.array([int(round(255 * c)) for c in rgba[:3]])
    return np.all(np.abs(image.astype(int) - target) <= TOLERANCE, axis=2)


def render_area(image):
    """The 3D view: the bounding box of the pixels of anafi.rviz's background colour (None when absent)."""
    rows, cols = np.nonzero(np.all(image == np.array(BACKGROUND), axis=2))
    if len(rows) < 10000:
        return None
    return image[rows.min():rows.max() + 1, cols.min():cols.max() + 1]


def dark_pixels(image):
    return int(np.all(image < 70, axis=2).sum())


def colour_counts(image):
    return dict((kind, int(colour_mask(image, rgba).sum())) for kind, rgba in COLOURS.items())


class MarkerWatch(object):
    """The markers published for the drone; restarts the scenario each time it is done, so the drone keeps
    flying the circle (and the MPC predicting) however long rviz takes to draw under load."""

    def __init__(self):
        self.kinds = {}
        self.restarts = 0
        rospy.Subscriber('/visualisation/markers', MarkerArray, self.on_markers, queue_size=5)
        self.command = rospy.Publisher('/%s/trajectory_generator/command' % DRONE, String, queue_size=2)
        rospy.Subscriber('/%s/trajectory/status' % DRONE, String, self.on_status, queue_size=5)

    def on_status(self, msg):
        try:
            state = yaml.safe_load(msg.data).get('state')
        except (yaml.YAMLError, AttributeError):
            return
        if state == 'done':
            self.restarts += 1
            self.command.publish(String('restart'))

    def on_markers(self, msg):
        for m in msg.markers:
            if m.ns.startswith(DRONE + '/') and m.action == m.ADD:
                self.kinds[m.ns.split('/', 1)[1]] = len(m.points)


class TestRviz(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        cls.procs = []
        cls.tmp = tempfile.mkdtemp(prefix='rviz_test_')
        rospy.init_node('test_rviz')
        cls.watch = MarkerWatch()

    @classmethod
    def tearDownClass(cls):
        for p in reversed(cls.procs):
            stop(p, grace=5.0)
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def start_xvfb(self):
        return start_xvfb(self.tmp, self.procs)

    def test_screenshot_shows_drone_and_paths(self):
        for tool in ('rviz', 'Xvfb'):
            if shutil.which(tool) is None:
                self.skipTest('%s is not installed (tools/setup.sh installs rviz and xvfb)' % tool)
        display, screen = self.start_xvfb()
        env = dict(os.environ, DISPLAY=display, LIBGL_ALWAYS_SOFTWARE='1')
        env.pop('WAYLAND_DISPLAY', None)
        log = open(os.path.join(self.tmp, 'rviz.log'), 'w')
        rviz = subprocess.Popen(['rviz', '-d', paths.config_path('anafi.rviz'), '__name:=test_rviz_gui'],
                                env=env, stdout=log, stderr=subprocess.STDOUT)
        self.procs.append(rviz)
        image, view, counts, dark = None, None, {}, 0
        deadline = time.time() + 200.0       # rviz start-up under software GL + take-off + 8 s hover
        while time.time() < deadline:
            time.sleep(2.0)
            self.assertIsNone(rviz.poll(), 'rviz exited (%s); log: %s' % (rviz.returncode, log.name))
            image = read_xwd(screen)
            view = render_area(image)
            if view is None:
                continue
            counts = colour_counts(view)
            dark = dark_pixels(view)
            if all(n >= MIN_PIXELS[k] for k, n in counts.items()) and dark >= MIN_DARK:
                break
        self.save(image)
        print('3D view %s px; pixels per colour: %s; dark (drone model): %d; scenario restarts: %d'
              % (None if view is None else view.shape[:2], counts, dark, self.watch.restarts))
        self.assertIsNotNone(view, 'no 3D view (background %s) on the screen' % (BACKGROUND,))
        self.assertGreater(float(view.std()), 5.0, 'uniform 3D view')
        for kind, n in counts.items():
            self.assertGreaterEqual(n, MIN_PIXELS[kind], '%s colour %s: %d pixels (all: %s)'
                                    % (kind, COLOURS[kind], n, counts))
        # the drone model: its dark grey body (nothing else in the 3D view is that dark)
        self.assertGreaterEqual(dark, MIN_DARK, 'no dark (drone model) pixels')
        self.assertTrue({'trail', 'reference', 'predicted', 'waypoint'} <= set(self.watch.kinds), self.watch.kinds)

    def save(self, image):
        import matplotlib
        matplotlib.use('Agg')
        import matplotlib.image
        targets = [os.path.join(paths.package_dir(), 'test_results', 'rviz.png')]
        if os.environ.get('ANAFI_RVIZ_SCREENSHOT'):
            targets.append(os.environ['ANAFI_RVIZ_SCREENSHOT'])
        for path in targets:
            os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
            matplotlib.image.imsave(path, image)
            print('screenshot: %s' % path)


if __name__ == '__main__':
    rostest.rosrun('anafi_sim', 'test_rviz', TestRviz, sys.argv)

"""anafi_sim.mission.evaluation: tracking-error statistics, alignment, garbage handling, the paper's Table 3
from the shipped reference logs, CSV and rosbag round trips, the live core and the command line.

Expected numbers are worked out by hand in the tests (3-4-5 triangles, sums written out) or come
from the paper (Table 3) and the reference logs' README (anafi_sim/data/reference_logs/README.md).
"""
import math
import os
import subprocess
import sys

import numpy as np
import pytest

from anafi_sim import paths
from anafi_sim.mission import evaluation as ev
from anafi_sim.mission.reference_log import read_log, write_log

REPO = paths.checkout()
REFERENCE_LOGS = paths.reference_logs_dir()     # shipped with the package
CLI = os.path.join(REPO, 'anafi_sim', 'scripts', 'evaluate_log.py')


# ---------------------------------------------------------------- statistics on hand-made data

def test_statistics_of_hand_made_errors():
    t = np.arange(4) * 0.05
    wp = np.tile([3.0, 2.0, 5.0], (4, 1))
    # offsets with lengths 1, 2, 3 (2-2-1 triangle), 5 (3-4-0)
    offsets = np.array([[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [2.0, 2.0, 1.0], [3.0, 4.0, 0.0]])
    result = ev.evaluate_arrays(t, wp, wp - offsets, name='hand')
    s = result.estimate.stats
    assert s.mean == pytest.approx((1 + 2 + 3 + 5) / 4.0)
    assert s.max == pytest.approx(5.0)
    mean = 11 / 4.0
    assert s.std == pytest.approx(math.sqrt(((1 - mean) ** 2 + (2 - mean) ** 2 + (3 - mean) ** 2 + (5 - mean) ** 2) / 4))
    assert result.estimate.stats_h.max == pytest.approx(5.0)
    assert result.estimate.stats_h.mean == pytest.approx((1 + 2 + math.sqrt(8) + 5) / 4.0)
    assert (s.n_valid, s.n_excluded) == (4, 0)
    assert result.truth is None                                # no ground truth given: absent, not garbage
    assert not result.has_garbage and result.garbage.summary() == []
    assert result.estimate.e_mu == s.mean and result.estimate.e_max == s.max and result.estimate.e_sigma == s.std


def test_drift_is_the_slope_of_the_error():
    t = np.arange(0, 10, 0.05)
    wp = np.column_stack([t, np.zeros_like(t), np.full_like(t, 7.0)])
    pos = wp - np.column_stack([0.5 + 0.1 * t, np.zeros_like(t), np.zeros_like(t)])
    r = ev.evaluate_arrays(t, wp, pos)
    assert r.estimate.drift == pytest.approx(0.1)
    assert r.estimate.e_mu == pytest.approx(0.5 + 0.1 * t.mean())


def test_zero_order_hold_alignment_and_samples_before_the_first_waypoint():
    values, valid = ev.align_zoh([1.0, 2.0, 3.0], [[10.0], [20.0], [30.0]], [0.5, 1.0, 1.99, 2.0, 7.0])
    assert valid.tolist() == [False, True, True, True, True]
    assert np.isnan(values[0, 0]) and values[1:, 0].tolist() == [10.0, 20.0 - 10.0, 20.0, 30.0]
    # drone at 20 Hz from t = 0, waypoint at 10 Hz from t = 0.12 stepping by 1 m per message
    t = np.arange(0, 1.0, 0.05)
    t_wp = 0.12 + np.arange(0, 1.0, 0.1)
    wp = np.column_stack([np.arange(len(t_wp)), np.zeros(len(t_wp)), np.zeros(len(t_wp))])
    r = ev.evaluate_arrays(t, wp, np.zeros((len(t), 3)), t_waypoint=t_wp)
    kept = t[t >= 0.12]
    assert r.n_samples == len(kept) and r.dropped_before_waypoint == len(t) - len(kept)
    expected = [math.floor((x - 0.12) / 0.1 + 1e-9) for x in kept]      # latest waypoint index = its x
    assert r.log.wp_x.tolist() == expected
    assert any('before the first waypoint' in w for w in r.warnings)


def test_truth_is_interpolated_and_missing_truth_is_reported():
    t = np.array([0.0, 0.1, 0.2, 0.3])
    wp = np.zeros((4, 3))
    truth_t = np.array([0.0, 0.2, 0.3])
    truth = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 3.0], [0.0, 0.0, 4.0]])
    r = ev.evaluate_arrays(t, wp, np.zeros((4, 3)), truth=truth, t_truth=truth_t)
    assert r.truth.e.tolist() == pytest.approx([1.0, 2.0, 3.0, 4.0])         # 2.0 interpolated at t = 0.1
    values = ev.interpolate([0.0, 1.0, 5.0], [[0.0], [1.0], [5.0]], [0.5, 2.0, 6.0], max_gap=2.0)
    assert values[0, 0] == pytest.approx(0.5)
    assert np.isnan(values[1, 0]) and np.isnan(values[2, 0])                 # gap 4 s > 2 s; outside
    yaw = ev.interpolate([0.0, 1.0], [[3.0], [-3.0]], [0.5], angle_columns=(0,))
    assert abs(abs(yaw[0, 0]) - math.pi) < 1e-9                              # across +-pi, not through 0


def test_all_zero_truth_columns_are_no_ground_truth():
    # a real-flight CSV has the *_sphinx columns filled with zeros: "no ground truth", not an error of |wp|
    t = np.arange(10) * 0.1
    wp = np.tile([5.0, 5.0, 1.0], (10, 1))
    r = ev.evaluate_arrays(t, wp, wp - [0.1, 0.0, 0.0], truth=np.zeros((10, 3)), t_truth=t)
    assert r.truth is None and r.estimate.stats.mean == pytest.approx(0.1)
    assert any('no ground truth' in line for line in r.lines())
    # a truth that is zero only at some samples (e.g. at the origin) is still ground truth
    truth = np.zeros((10, 3))
    truth[5:] = [5.0, 5.0, 1.0]
    assert ev.evaluate_arrays(t, wp, wp, truth=truth, t_truth=t).truth is not None


def test_garbage_is_excluded_and_reported():
    n = 20
    t = np.arange(n) * 0.05
    wp = np.tile([3.0, 2.0, 5.0], (n, 1))
    pos = wp - [0.0, 0.0, 1.0]
    pos[::4, 2] = 65280.0                              # the 16-bit wrap glitch in 5 samples
    pos[3, 0] = float('nan')
    r = ev.evaluate_arrays(t, wp, pos, name='glitch')
    assert r.has_garbage
    assert set(r.garbage.columns) == {'z_anafi', 'x_anafi'}
    assert r.garbage.columns['z_anafi'].reasons == {'16-bit wrap': 5}
    assert r.garbage.columns['x_anafi'].reasons == {'non-finite': 1}
    s = r.estimate.stats
    assert (s.n_valid, s.n_excluded) == (14, 6)
    assert (s.mean, s.max, s.std) == pytest.approx((1.0, 1.0, 0.0))      # the garbage is not averaged in
    assert r.estimate.stats_h.n_valid == 19                               # only x/y garbage hits e_h
    assert any('z_anafi' in line and 'GARBAGE' in line for line in r.lines())
    assert r.as_dict()['garbage'] == r.garbage.summary()


def test_below_ground_positions_are_excluded_and_reported():
    t = np.arange(5) * 0.05
    wp = np.tile([0.0, 0.0, 7.0], (5, 1))
    truth = np.tile([0.5, 0.0, 7.0], (5, 1))
    truth[1:3, 2] = -111.0
    r = ev.evaluate_arrays(t, wp, wp - [0.1, 0.0, 0.0], truth=truth)
    assert r.truth.excluded == {'below ground': 2}
    assert r.truth.stats.n_valid == 3 and r.truth.e_mu == pytest.approx(0.5)
    assert r.truth.stats_h.n_valid == 5
    assert any('below ground' in w for w in r.warnings)
    r2 = ev.evaluate_arrays(t, wp, wp - [0.1, 0.0, 0.0], truth=truth, min_altitude=None)
    assert r2.truth.stats.n_valid == 5


def test_window_restricts_samples():
    t = np.arange(0, 10, 0.1)
    wp = np.zeros((len(t), 3))
    pos = np.column_stack([t, np.zeros_like(t), np.zeros_like(t)])
    r = ev.evaluate_arrays(t, wp, pos, window=(2.0, 4.0))
    assert r.window == (2.0, 4.0) and r.n_samples == 21            # 2.0, 2.1, ... 4.0
    assert r.estimate.e_max == pytest.approx(4.0) and r.estimate.e_mu == pytest.approx(3.0)
    with pytest.raises(ValueError):
        ev.evaluate_arrays(t, wp, pos, window=(4.0, 2.0))
    assert ev.measured_window([10, 50], [40, 60, 70]) == (50, 60)              # last begin, first end after
    assert ev.measured_window([10], []) == (10, None)
    assert ev.measured_window([], [5]) is None


# ---------------------------------------------------------------- the paper's reference logs

PAPER_TABLE_3 = {'mpc': [0.16, 0.36, 0.59, 0.82, 1.41], 'pid': [1.32, 2.67, 4.07, 5.32, 7.00]}
# x_straight_4_pid.csv gives 5.293 m against the paper's 5.32 (the published file is half-float
# quantised, 0.0625 m steps at x = 64-128 m, and may not be the exact segment the paper averaged).
TOLERANCE = {('pid', 4): 0.03}
GLITCHED = {('pid', 2): 2.57, ('pid', 3): 4.12}      # horizontal e_mu per the reference logs' README


@pytest.mark.parametrize('controller', ['mpc', 'pid'])
@pytest.mark.parametrize('speed', [1, 2, 3, 4, 5])
def test_reference_logs_reproduce_table_3(controller, speed):
    r = ev.evaluate_csv(os.path.join(REFERENCE_LOGS, 'x_straight_%d_%s.csv' % (speed, controller)))
    paper = PAPER_TABLE_3[controller][speed - 1]
    if (controller, speed) in GLITCHED:
        assert list(r.garbage.columns) == ['z_anafi']
        assert r.garbage.columns['z_anafi'].count == r.n_samples
        assert r.garbage.columns['z_anafi'].reasons == {'16-bit wrap': r.n_samples}
        assert math.isnan(r.estimate.e_mu) and r.estimate.stats.n_valid == 0     # not averaged in
        assert r.estimate.stats_h.mean == pytest.approx(GLITCHED[(controller, speed)], abs=0.01)
        assert abs(r.estimate.stats_h.mean - paper) < 0.11
    else:
        assert not r.has_garbage
        assert r.estimate.stats.n_valid == r.n_samples
        assert r.estimate.e_mu == pytest.approx(paper, abs=TOLERANCE.get((controller, speed), 0.01))
        assert r.estimate.e_max >= r.estimate.e_mu >= 0 and r.estimate.e_sigma > 0
        assert r.truth is not None and r.truth.stats.n_valid == r.n_samples


def test_only_the_two_glitched_reference_logs_are_flagged():
    flagged = sorted(name for name in os.listdir(REFERENCE_LOGS) if name.endswith('.csv')
                     and ev.evaluate_csv(os.path.join(REFERENCE_LOGS, name)).has_garbage)
    assert flagged == ['x_straight_2_pid.csv', 'x_straight_3_pid.csv']


def test_csv_round_trip_gives_the_same_statistics(tmp_path):
    path = os.path.join(REFERENCE_LOGS, 'x_straight_1_mpc.csv')
    first = ev.evaluate_csv(path)
    out = str(tmp_path / 'copy.csv')
    write_log(out, first.log)
    again = ev.evaluate_csv(out)
    assert again.estimate.stats == first.estimate.stats and again.truth.stats == first.truth.stats
    window = ev.evaluate_csv(path, window=(2.0, 5.0))
    log = read_log(path)
    rows = (log.t >= 2.0) & (log.t <= 5.0)
    e = np.sqrt((log.wp_x - log.x_anafi) ** 2 + (log.wp_y - log.y_anafi) ** 2 + (log.wp_z - log.z_anafi) ** 2)
    assert window.window == (2.0, 5.0) and window.n_samples == rows.sum() > 50
    assert window.estimate.e_mu == pytest.approx(e[rows].mean()) and window.estimate.e_max == pytest.approx(e[rows].max())


# ---------------------------------------------------------------- messages, bags, live

class _Obj(object):
    def __init__(self, **kw):
        self.__dict__.update(kw)


def test_odometry_twist_is_rotated_into_the_world_frame():
    from nav_msgs.msg import Odometry
    from anafi_control.frames import euler_to_quaternion
    m = Odometry()
    m.header.frame_id, m.child_frame_id = 'world', 'anafi/base_link'
    q = euler_to_quaternion(0.0, 0.0, math.pi / 2)
    m.pose.pose.orientation.x, m.pose.pose.orientation.y, m.pose.pose.orientation.z, m.pose.pose.orientation.w = q
    m.pose.pose.position.x = 1.0
    m.twist.twist.linear.x = 2.0                        # forward in the body = +y in the world at yaw 90 deg
    s = ev.state_from_odometry(m)
    assert s[:6] == pytest.approx((1.0, 0.0, 0.0, 0.0, 2.0, 0.0), abs=1e-12)
    assert s[8] == pytest.approx(math.pi / 2)
    m.child_frame_id = 'world'                          # twist already in the world frame
    assert ev.state_from_odometry(m)[3:6] == pytest.approx((2.0, 0.0, 0.0))


def waypoint_class():
    """anafi_sim/Waypoint: the generated class when the workspace is sourced, else built from msg/."""
    try:
        from anafi_sim.msg import Waypoint
        return Waypoint
    except ImportError:
        import genpy.dynamic
        from std_msgs.msg import Header
        with open(os.path.join(REPO, 'msg', 'Waypoint.msg')) as f:
            text = f.read()
        full = text + '\n' + '=' * 80 + '\nMSG: std_msgs/Header\n' + Header._full_text
        return genpy.dynamic.generate_dynamic('anafi_sim/Waypoint', full)['anafi_sim/Waypoint']


def _flight(n=60, rate=20.0, t0=1000.0):
    """A drone trailing a waypoint moving at 1 m/s along +x by 0.3 m (estimate) / 0.2 m (truth)."""
    import rospy
    from nav_msgs.msg import Odometry
    from std_msgs.msg import Header
    Waypoint = waypoint_class()
    wps, est, truth = [], [], []
    for i in range(n):
        t = t0 + i / rate
        stamp = rospy.Time.from_sec(t)
        if i % 2 == 0:                                   # waypoint at 10 Hz
            w = Waypoint()
            w.header.stamp = stamp
            w.x, w.z, w.vx = t - t0, 5.0, 1.0
            wps.append((stamp, w))
        for lag, out in ((0.3, est), (0.2, truth)):
            o = Odometry()
            o.header.stamp, o.header.frame_id, o.child_frame_id = stamp, 'world', 'anafi/base_link'
            o.pose.pose.orientation.w = 1.0
            o.pose.pose.position.x = (t0 + (i // 2) * 2 / rate) - t0 - lag   # vs the held waypoint
            o.pose.pose.position.z = 5.0
            out.append((stamp, o))
    begin = Header(stamp=rospy.Time.from_sec(t0 + 0.5), frame_id='test')
    end = Header(stamp=rospy.Time.from_sec(t0 + 2.0), frame_id='test')
    return Waypoint, wps, est, truth, begin, end


def test_messages_are_evaluated_over_the_begin_end_window():
    _, wps, est, truth, begin, end = _flight()
    r = ev.evaluate_messages(wps, est, truth, [(begin.stamp, begin)], [(end.stamp, end)], name='m')
    assert r.estimate.e_mu == pytest.approx(0.3) and r.estimate.e_max == pytest.approx(0.3)
    assert r.truth.e_mu == pytest.approx(0.2)
    assert r.n_samples == 31                             # 0.5 .. 2.0 s at 20 Hz, both ends included
    whole = ev.evaluate_messages(wps, est)
    assert whole.n_samples == 60 and whole.truth is None
    bad = list(est) + [(est[-1][0], _Obj(header=None))]
    r2 = ev.evaluate_messages(wps, bad, name='bad')
    assert any('malformed estimate' in w for w in r2.warnings)


def _write_bag(path, flight, drone='anafi'):
    import rosbag
    _, wps, est, truth, begin, end = flight
    with rosbag.Bag(path, 'w') as bag:
        for stamp, m in wps:
            bag.write('/%s/position_control/waypoint' % drone, m, stamp)
        for stamp, m in est:
            bag.write('/%s/drone/odom' % drone, m, stamp)
        for stamp, m in truth:
            bag.write('/%s/ground_truth/odom' % drone, m, stamp)
        bag.write('/%s/trajectory/begin' % drone, begin, begin.stamp)
        bag.write('/%s/trajectory/end' % drone, end, end.stamp)


def test_bag_round_trip(tmp_path):
    rosbag = pytest.importorskip('rosbag')
    flight = _flight()
    path = str(tmp_path / 'flight.bag')
    _write_bag(path, flight)
    with rosbag.Bag(path) as bag:
        r = ev.evaluate_bag(bag, name='flight')
    direct = ev.evaluate_messages(*flight[1:4], begins=[(flight[4].stamp, flight[4])],
                                  ends=[(flight[5].stamp, flight[5])])
    assert r.estimate.stats == direct.estimate.stats and r.truth.stats == direct.truth.stats
    assert r.estimate.e_mu == pytest.approx(0.3) and r.n_samples == 31
    assert r.topics['estimate'] == '/anafi/drone/odom'
    with rosbag.Bag(path) as bag:
        r2 = ev.evaluate_bag(bag, window=(0.0, 0.45))            # explicit window overrides begin/end
    assert r2.n_samples == 10


def test_bag_topic_selection():
    types = {'/a/drone/odom': 'nav_msgs/Odometry', '/b/drone/odom': 'nav_msgs/Odometry',
             '/a/position_control/waypoint': 'anafi_sim/Waypoint', '/b/position_control/waypoint': 'anafi_sim/Waypoint'}
    with pytest.raises(ValueError, match='several'):
        ev.select_bag_topics(types)
    chosen = ev.select_bag_topics(types, drone='b')
    assert chosen['estimate'] == '/b/drone/odom' and chosen['truth'] is None
    with pytest.raises(ValueError, match='no waypoint'):
        ev.select_bag_topics({'/a/drone/odom': 'nav_msgs/Odometry'})


def test_live_evaluator_window_and_completion():
    live = ev.LiveEvaluator(name='live')
    assert live.evaluate() is None and live.state == 'waiting'
    for i in range(40):
        t = 10.0 + i * 0.05
        live.add_waypoint(t, (0.0, 0.0, 5.0, 0.0, 0.0, 0.0, 0.0))
        live.add_estimate(t, (0.0, 0.0, 5.0 - (0.5 if i >= 20 else 0.1), 0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
        if i == 20:
            live.begin(t)
        if i == 30:
            live.end(t)
            assert live.state == 'ended' and live.complete()     # the sample at the end stamp is in
    r = live.evaluate()
    assert r.n_samples == 11 and r.estimate.e_mu == pytest.approx(0.5)
    assert r.truth is None
    assert not live.add_estimate(11.0, (1.0, 2.0))                 # malformed: rejected and counted
    assert any('malformed estimate' in w for w in live.evaluate().warnings)
    small = ev.LiveEvaluator(max_samples=5)
    for i in range(8):
        small.add_waypoint(i, (0.0,) * 7)
        small.add_estimate(i, (0.0,) * 9)
    assert small.counts()['estimate'] == 5
    assert any('dropped' in w for w in small.evaluate().warnings)


# ---------------------------------------------------------------- command line

def _run_cli(*args):
    env = dict(os.environ)
    env['PYTHONPATH'] = REPO + os.pathsep + env.get('PYTHONPATH', '')
    p = subprocess.run([sys.executable, CLI] + list(args), stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                       universal_newlines=True, env=env, timeout=60)
    return p.returncode, p.stdout


def test_command_line_on_csv_and_bag(tmp_path):
    pytest.importorskip('rosbag')
    bag = str(tmp_path / 'flight.bag')
    _write_bag(bag, _flight())
    out_yaml = str(tmp_path / 'all.yaml')
    code, text = _run_cli(os.path.join(REFERENCE_LOGS, 'x_straight_3_pid.csv'),
                          os.path.join(REFERENCE_LOGS, 'x_straight_1_mpc.csv'), bag,
                          '--yaml', out_yaml, '--csv-dir', str(tmp_path / 'csv'))
    assert code == 0, text
    assert 'GARBAGE z_anafi: 255 of 255 samples (16-bit wrap: 255)' in text
    assert 'e_mu  0.165' in text
    assert 'flight: 31 samples' in text
    import yaml
    summaries = yaml.safe_load(open(out_yaml))
    assert [s['name'] for s in summaries] == ['x_straight_3_pid', 'x_straight_1_mpc', 'flight']
    assert summaries[2]['estimate']['e_mu'] == pytest.approx(0.3)
    assert len(read_log(str(tmp_path / 'csv' / 'flight.csv'))) == 31
    code, text = _run_cli(os.path.join(REFERENCE_LOGS, 'x_straight_2_pid.csv'), '--fail-on-garbage')
    assert code == 3
    code, text = _run_cli(str(tmp_path / 'missing.csv'))
    assert code == 1 and 'ERROR' in text


def test_one_bad_truth_sample_is_one_garbage_line_not_one_per_column():
    n = 20
    t = np.arange(n) * 0.05
    wp = np.tile([3.0, 2.0, 5.0], (n, 1))
    truth = wp - [0.0, 0.0, 0.5]
    truth[7] = float('nan')                            # one sample: x, y and z of the ground truth
    r = ev.evaluate_arrays(t, wp, wp - [0.0, 0.0, 1.0], truth=truth, name='nan')
    assert set(r.garbage.columns) == {'x_sphinx', 'y_sphinx', 'z_sphinx'}
    lines = r.garbage.summary()
    bad = r.garbage.columns['x_sphinx'].count          # the interpolation may carry it to a neighbour
    assert 1 <= bad <= 2
    assert lines == ['x_sphinx, y_sphinx, z_sphinx: %d of 20 samples (non-finite: %d)' % (bad, bad)]
    assert sum('GARBAGE' in line for line in r.lines()) == 1
    assert r.as_dict()['garbage_samples'] == bad and r.truth.stats.n_excluded == bad


def test_samples_without_ground_truth_are_counted_once_as_missing_not_as_garbage():
    t_est = np.arange(40) * 0.05                       # 0 .. 1.95 s
    t_truth = np.concatenate([np.arange(0.0, 0.5, 0.01), np.arange(1.5, 2.0, 0.01)])   # a 1 s gap
    est = np.tile([1.0, 2.0, 5.0, 0, 0, 0, 0, 0, 0], (len(t_est), 1))
    truth = np.tile([1.0, 2.0, 4.9, 0, 0, 0, 0, 0, 0], (len(t_truth), 1))
    wp = np.array([[1.0, 2.0, 5.0, 0.0, 0.0, 0.0, 0.0]])
    log, info = ev.build_log(np.round(t_est * 1e9).astype(np.int64), est, np.array([0], dtype=np.int64), wp,
                             np.round(t_truth * 1e9).astype(np.int64), truth, name='gap')
    r = ev.evaluate_log(log, absent=info['absent'])
    assert 10 <= r.truth_missing <= 22
    assert not r.has_garbage and r.garbage.summary() == []
    assert [w for w in r.warnings if 'ground truth missing' in w] == [
        'ground truth missing (no sample within the interpolation gap) at %d samples' % r.truth_missing]
    assert r.as_dict()['truth_missing'] == r.truth_missing and r.truth.stats.n_valid == 40 - r.truth_missing

"""anafi_sim.ros.node: diagnostics building/publishing, ~params and start-up glue (no ROS master needed)."""
import threading

import pytest

rospy = pytest.importorskip('rospy')
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402

from anafi_sim.ros.params import ParamError  # noqa: E402
from anafi_sim.ros import node  # noqa: E402


class FakePublisher(object):
    """Records published messages; raises ROSException (as a closed publisher does) from call ``fail_at``."""

    def __init__(self, fail_at=None):
        self.sent = []
        self.fail_at = fail_at

    def publish(self, msg):
        if self.fail_at is not None and len(self.sent) + 1 >= self.fail_at:
            raise rospy.ROSException('publish() to a closed topic')
        self.sent.append(msg)


@pytest.fixture
def ros_time(monkeypatch):
    """rospy.Time.now() without init_node: a fixed time."""
    monkeypatch.setattr(rospy.Time, 'now', staticmethod(lambda: rospy.Time(12, 500)))


def test_diagnostic_status_fields_and_string_values():
    st = node.diagnostic_status('pid_command: /anafi/pid_command', DiagnosticStatus.WARN, 'hover command: x',
                                [('commands sent', 3), ('enabled', True), ('last effort', '0.5'),
                                 ('ratio', 0.25)], hardware_id='anafi')
    assert isinstance(st, DiagnosticStatus)
    assert (st.name, st.level, st.message, st.hardware_id) == \
        ('pid_command: /anafi/pid_command', DiagnosticStatus.WARN, 'hover command: x', 'anafi')
    assert [(kv.key, kv.value) for kv in st.values] == \
        [('commands sent', '3'), ('enabled', 'True'), ('last effort', '0.5'), ('ratio', '0.25')]


def test_diagnostic_status_defaults_and_serializes():
    st = node.diagnostic_status('n', DiagnosticStatus.ERROR, 'hover: solver failed', iter([(1, None)]))
    assert st.hardware_id == ''
    assert [(kv.key, kv.value) for kv in st.values] == [('1', 'None')]
    # what goes on the wire decodes to the same status (types accepted by the message)
    import io
    buf = io.BytesIO()
    DiagnosticArray(status=[st]).serialize(buf)
    back = DiagnosticArray().deserialize(buf.getvalue())
    assert back.status[0].level == DiagnosticStatus.ERROR
    assert back.status[0].message == 'hover: solver failed'
    assert back.status[0].values[0].key == '1'


def test_publish_diagnostics_stamps_one_array(ros_time):
    pub = FakePublisher()
    statuses = [node.diagnostic_status('a', DiagnosticStatus.OK, 'ok', []),
                node.diagnostic_status('b', DiagnosticStatus.WARN, 'w', [])]
    assert node.publish_diagnostics(pub, statuses) is True
    assert len(pub.sent) == 1
    assert pub.sent[0].header.stamp == rospy.Time(12, 500)
    assert [s.name for s in pub.sent[0].status] == ['a', 'b']


def test_publish_diagnostics_false_when_publisher_closed(ros_time):
    assert node.publish_diagnostics(FakePublisher(fail_at=1), []) is False


def test_diagnostics_thread_stops_when_publisher_closes(ros_time):
    calls = []

    def make_statuses():
        calls.append(1)
        return [node.diagnostic_status('t', DiagnosticStatus.OK, 'n=%d' % len(calls), [])]

    pub = FakePublisher(fail_at=3)
    thread = node.start_diagnostics_thread(0.0, make_statuses, pub)
    assert thread.daemon
    thread.join(10.0)
    assert not thread.is_alive()
    assert [a.status[0].message for a in pub.sent] == ['n=1', 'n=2']
    assert len(calls) == 3


def test_private_params_reads_tilde_names(monkeypatch):
    store = {'~rate': 20, '~topic': ' a/b '}
    monkeypatch.setattr(rospy, 'get_param', lambda name, default=None: store.get(name, default))
    p = node.private_params()
    assert p.positive('rate', 30.0) == 20.0
    assert p.positive('missing', 7.0) == 7.0
    assert p.string('topic', '') == 'a/b'
    store['~rate'] = -1
    with pytest.raises(ParamError, match='~rate'):
        p.positive('rate', 30.0)


def _stub_start_up(monkeypatch):
    log = []
    monkeypatch.setattr(rospy, 'init_node', lambda name, **kw: log.append(('init', name)))
    monkeypatch.setattr(node, 'install_shutdown_signals', lambda: None)    # the test process keeps its handlers
    monkeypatch.setattr(rospy, 'get_name', lambda: '/anafi/x')
    monkeypatch.setattr(rospy, 'logfatal', lambda fmt, *args: log.append(('fatal', fmt % args)))
    return log


def test_run_node_bad_parameters_log_fatal_and_exit(monkeypatch):
    log = _stub_start_up(monkeypatch)

    def factory():
        raise ParamError('~rate must be a finite number > 0, got -1')

    with pytest.raises(SystemExit) as exit_info:
        node.run_node('x', factory, fatal_exit_code=3)
    assert exit_info.value.code == 3
    assert log == [('init', 'x'), ('fatal', '/anafi/x: bad parameters: ~rate must be a finite number > 0, got -1')]


def test_a_respawned_node_with_bad_parameters_stays_up_in_error_until_shutdown(monkeypatch):
    log = _stub_start_up(monkeypatch)
    published, shutdown = [], threading.Event()

    def diagnostics_thread(period, make_statuses, pub, first=None):
        published.extend(make_statuses())
        shutdown.set()               # the launch stops the node after its first ERROR diagnostic

    monkeypatch.setattr(node, 'diagnostics_publisher', lambda: None)
    monkeypatch.setattr(node, 'start_diagnostics_thread', diagnostics_thread)
    monkeypatch.setattr(rospy, 'is_shutdown', shutdown.is_set)

    def factory():
        raise ParamError('~rtf must be a finite number > 0, got -1')

    with pytest.raises(SystemExit) as exit_info:
        node.run_node('x', factory, fatal_exit_code=2, respawned=True)
    assert exit_info.value.code == 2       # only once stopped: roslaunch does not respawn a node that is up
    assert log[0] == ('init', 'x') and len(log) == 2 and log[1][0] == 'fatal'
    assert 'bad parameters: ~rtf must be' in log[1][1] and 'staying up in ERROR' in log[1][1]
    [status] = published
    assert status.level == node.ERROR and status.name == '/anafi/x: bad parameters'
    assert status.message == 'bad parameters: ~rtf must be a finite number > 0, got -1'


def test_run_node_runs_the_node(monkeypatch):
    log = _stub_start_up(monkeypatch)
    ran = threading.Event()

    class Node(object):
        def run(self):
            ran.set()

    node.run_node('x', Node)
    assert ran.is_set()
    assert log == [('init', 'x')]


@pytest.mark.parametrize('namespace, expected', [('/anafi/', 'anafi'), ('/', 'anafi'), ('/a/b/', 'a/b')])
def test_namespace_id(monkeypatch, namespace, expected):
    monkeypatch.setattr(rospy, 'get_namespace', lambda: namespace)
    assert node.namespace_id() == expected


# --- the level table, health statuses, the thread's options --------------------------------------

def test_level_table_maps_every_core_level():
    from anafi_sim.interface import ground_truth
    assert node.LEVELS == {ground_truth.OK: DiagnosticStatus.OK, ground_truth.WARN: DiagnosticStatus.WARN,
                           ground_truth.ERROR: DiagnosticStatus.ERROR}
    health = ground_truth.Health(ground_truth.ERROR, 'stale', [('sample age [s]', '1.000')])
    st = node.health_status('interface', health, 'anafi', [('publish errors', 0)])
    assert (st.level, st.message, st.hardware_id) == (DiagnosticStatus.ERROR, 'stale', 'anafi')
    assert [(kv.key, kv.value) for kv in st.values] == [('sample age [s]', '1.000'), ('publish errors', '0')]


def test_publish_diagnostics_with_a_given_stamp(ros_time):
    pub = FakePublisher()
    assert node.publish_diagnostics(pub, [], stamp=rospy.Time(3, 0))
    assert pub.sent[0].header.stamp == rospy.Time(3, 0)


def test_diagnostics_thread_first_at_once_own_stamp_and_survives_errors(ros_time, monkeypatch):
    errors = []
    monkeypatch.setattr(rospy, 'logerr_throttle', lambda period, text: errors.append(text))
    monkeypatch.setattr(rospy, 'get_name', lambda: '/anafi/x')
    calls = []

    def make_statuses():
        calls.append(1)
        if len(calls) == 2:
            raise KeyError('boom')
        return []

    pub = FakePublisher(fail_at=3)
    thread = node.start_diagnostics_thread(60.0, make_statuses, pub, stamp=lambda: rospy.Time(7, 0), first=0.0)
    thread.join(0.5)
    assert thread.is_alive() and len(pub.sent) == 1     # the first one at once, the next after 60 s
    assert pub.sent[0].header.stamp == rospy.Time(7, 0)
    pub2 = FakePublisher(fail_at=3)
    calls[:] = []
    thread = node.start_diagnostics_thread(0.0, make_statuses, pub2)
    thread.join(10.0)
    assert not thread.is_alive() and len(pub2.sent) == 2 and len(calls) == 4   # call 2 failed, logged, went on
    assert errors == ["/anafi/x: diagnostics failed: KeyError: 'boom'"]


@pytest.mark.parametrize('result, code', [(False, 1), (3, 3)])
def test_run_node_exit_status_from_run(monkeypatch, result, code):
    _stub_start_up(monkeypatch)

    class Node(object):
        def run(self):
            return result

    with pytest.raises(SystemExit) as exit_info:
        node.run_node('x', Node)
    assert exit_info.value.code == code
    assert node.run_node('x', type('Ok', (), {'run': lambda self: True})) is None


def test_run_node_passes_init_options_and_shuts_down_without_signals(monkeypatch):
    log = []
    monkeypatch.setattr(rospy, 'init_node', lambda name, **kw: log.append(('init', name, kw)))
    monkeypatch.setattr(rospy, 'get_name', lambda: '/m')
    monkeypatch.setattr(rospy, 'logfatal', lambda fmt, *args: log.append(('fatal', fmt % args)))
    monkeypatch.setattr(rospy, 'signal_shutdown', lambda reason: log.append(('shutdown', reason)))

    def factory():
        raise ValueError('~urdf_file: no such file: x')

    with pytest.raises(SystemExit) as exit_info:
        node.run_node('m', factory, fatal_exit_code=2, disable_signals=True)
    assert exit_info.value.code == 2
    assert log == [('init', 'm', {'disable_signals': True}), ('fatal', '/m: bad parameters: ~urdf_file: no such '
                                                                         'file: x'), ('shutdown', 'bad parameters')]


def test_log_lines_and_wait_for_clock(monkeypatch):
    log = []
    for level in ('loginfo', 'logwarn', 'logerr'):
        monkeypatch.setattr(rospy, level, lambda text, level=level: log.append((level, text)))
    node.log_lines([('info', 'a'), ('warn', 'b'), ('error', 'c')])
    assert log == [('loginfo', 'a'), ('logwarn', 'b'), ('logerr', 'c')]
    times = iter([0.0, 0.0, 1.5])
    monkeypatch.setattr(rospy, 'get_param', lambda name, default=None: True)
    monkeypatch.setattr(rospy, 'is_shutdown', lambda: False)
    monkeypatch.setattr(rospy, 'get_time', lambda: next(times))
    node.wait_for_clock(poll=0.0)
    with pytest.raises(StopIteration):
        next(times)


def test_the_timer_survives_time_going_back_counts_it_and_survives_a_failing_callback(monkeypatch):
    made, warned, errors = [], [], []
    monkeypatch.setattr(rospy, 'Timer', lambda period, cb, reset=False: made.append((period, cb, reset)))
    monkeypatch.setattr(rospy, 'get_name', lambda: '/anafi/mpc_controller')
    monkeypatch.setattr(rospy, 'logwarn', lambda fmt, *args: warned.append(fmt % args))
    monkeypatch.setattr(rospy, 'logerr_throttle', lambda period, text: errors.append(text))
    calls = []

    def callback(event):
        calls.append(event.current_real.to_sec())
        if len(calls) == 3:
            raise RuntimeError('bad cycle')

    timer = node.Timer(0.1, callback, 'control')
    [(period, on_event, reset)] = made
    assert reset is True and abs(period.to_sec() - 0.1) < 1e-12      # rospy resets instead of raising
    for t in (100.0, 100.1, 95.0, 95.1):
        on_event(rospy.timer.TimerEvent(None, None, None, rospy.Time.from_sec(t), None))
    assert [round(c, 6) for c in calls] == [100.0, 100.1, 95.0, 95.1]
    assert timer.jumps_back == 1 and abs(timer.last_jump - 5.1) < 1e-6
    assert warned == ['/anafi/mpc_controller: ROS time moved backwards by 5.100 s (1 times): control timer kept '
                      'running']
    assert timer.callback_errors == 1 and 'RuntimeError: bad cycle' in errors[0]


_SIGNALLED_NODE = r'''
import sys, threading, time
import rospy
from anafi_sim.ros import node

master_lock = threading.Lock()       # as rospy's master proxy lock: held by the main thread in a call to the master
stuck = sys.argv[1] == 'stuck'


def signal_shutdown(reason):
    with master_lock:                # rospy's shutdown unregisters through the same proxy
        print('shutdown: %s' % reason, flush=True)
        rospy.core._shutdown_flag = True


rospy.signal_shutdown = signal_shutdown
node.install_shutdown_signals(grace=float(sys.argv[2]))
with master_lock:
    print('in a call to the master', flush=True)
    time.sleep(1.0)                  # the signal lands here
while not rospy.is_shutdown() or stuck:
    time.sleep(0.05)
print('main loop ended', flush=True)
'''


@pytest.mark.parametrize('case', ['ends', 'stuck', 'second signal'])
def test_a_signal_during_a_call_to_the_master_ends_the_node(tmp_path, case):
    """SIGINT while the main thread holds the master proxy's lock: the shutdown runs beside it (rospy's handler,
    run on top of the main thread, would wait for that lock forever); a node that does not end by itself ends
    after the grace, or at a second signal, with one line naming why."""
    import os
    import signal
    import subprocess
    import sys
    script = tmp_path / 'signalled_node.py'
    script.write_text(_SIGNALLED_NODE)
    proc = subprocess.Popen([sys.executable, str(script), 'stuck' if case != 'ends' else 'ends',
                             '0.5' if case == 'stuck' else '600'], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, universal_newlines=True)
    assert proc.stdout.readline().strip() == 'in a call to the master'
    proc.send_signal(signal.SIGINT)
    if case == 'second signal':
        assert proc.stdout.readline().strip() == 'shutdown: signal-2'
        proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 0
    if case == 'ends':
        assert out.splitlines()[-2:] == ['shutdown: signal-2', 'main loop ended'] and err == ''
    elif case == 'stuck':
        assert 'main loop ended' not in out and 'still running 0.5 s after signal 2; ending now' in err
    else:
        assert 'signal %d during shutdown; ending now' % signal.SIGTERM in err

"""Telemetry stream identity: the stand-in's streamId line, the interface refusing another drone's stream,
and the interface learning the simulator's port (telemetry_port 0) -- loopback, no ROS."""
import os
import sys
import threading
import time

import pytest

from anafi_sim.interface.ground_truth import ERROR, GroundTruthInterface
from anafi_sim.interface.supervisor import ProcessSupervisor
from anafi_sim.interface.telemetry_source import SimulatorSource, with_port
from anafi_sim.telemetry.protocol import (FIELDS, STREAM_ID_KEY, STREAM_ID_MAX, TelemetryParser, TelemetrySample,
                                          format_sample, new_stream_id)
from anafi_sim.telemetry.server import TelemetryServer
from conftest import ROOT

REPO = ROOT
LOGGER = os.path.join(REPO, 'anafi_sim', 'scripts', 'tlm_data_logger.py')


def sample(t, x=1.0):
    values = dict((f, 0.0) for f in FIELDS)
    values.update(x=x, z=2.0, timestamp=t)
    return TelemetrySample(**values)


def feed(parser, text):
    out = []
    for line in text.splitlines(True):
        s = parser.feed_line(line)
        if s is not None:
            out.append((s, parser.stream_id))
    return out


def test_the_stand_in_marks_every_sample_with_its_stream_id_and_the_parser_reads_it():
    text = format_sample(sample(0.01), stream_id=12345) + '\n' + format_sample(sample(0.02), stream_id=12345)
    assert text.startswith('omniscient_anafi.%s : 12345\n' % STREAM_ID_KEY)
    parser = TelemetryParser()
    got = feed(parser, text)
    assert [(s.timestamp, i) for s, i in got] == [(0.01, 12345), (0.02, 12345)]
    assert parser.malformed == 0 and parser.unknown_key == 0


def test_a_stream_without_id_reads_as_before_like_the_real_tool():
    parser = TelemetryParser()
    got = feed(parser, format_sample(sample(0.01)).replace(' : ', ': '))   # the real tool's "key: value"
    assert len(got) == 1 and got[0][1] is None


@pytest.mark.parametrize('value', ['0', '-3', '1.5', 'nan', str(STREAM_ID_MAX + 1), 'abc'])
def test_a_bad_stream_id_is_malformed_and_changes_nothing(value):
    parser = TelemetryParser()
    parser.feed_line('omniscient_anafi.streamId : 7\n')
    parser.feed_line('omniscient_anafi.streamId : %s\n' % value)
    assert parser.stream_id == 7 and parser.malformed == 1


def test_new_stream_ids_are_in_range_and_differ():
    ids = set(new_stream_id() for _ in range(50))
    assert all(1 <= i <= STREAM_ID_MAX for i in ids) and len(ids) > 45
    assert new_stream_id(lambda n: b'\x00' * n) == 1 and new_stream_id(lambda n: b'\xff' * n) == 2


def test_the_interface_refuses_another_stream_id_and_a_stream_without_id_when_it_expects_one():
    core = GroundTruthInterface(publish_rate=100.0, stale_timeout=0.5)
    core.expected_stream_id = 11
    assert core.on_sample(sample(0.01), 100.0, 22) is None
    assert core.on_sample(sample(0.02), 100.01, None) is None
    assert core.foreign_samples == 2 and core.published == 0 and core.last_foreign_id is None
    health = core.health(100.02)
    assert health.level == ERROR
    assert 'refusing the telemetry of another drone' in health.message and 'expected stream id 11' in health.message
    assert dict(health.values)['refused samples of another stream'] == '2'
    assert core.on_sample(sample(0.03), 100.03, 11) is not None
    assert core.health(100.04).level != ERROR or 'refusing' not in core.health(100.04).message


def test_without_an_expected_id_any_stream_is_read():
    core = GroundTruthInterface()
    assert core.on_sample(sample(0.01), 1.0, 99) is not None
    assert core.on_sample(sample(0.02), 1.01, None) is not None
    assert core.foreign_samples == 0


def test_with_port_replaces_the_endpoint_port():
    assert with_port(['tlm-data-logger', '-r', '0', 'inet:127.0.0.1:0'], 40123) == \
        ['tlm-data-logger', '-r', '0', 'inet:127.0.0.1:40123']
    with pytest.raises(ValueError):
        with_port(['tlm-data-logger', '-r', '0'], 1)


def test_the_source_waits_for_the_simulator_and_refuses_bad_values():
    params = {}
    source = SimulatorSource('anafi_sim', params.get)
    with pytest.raises(ValueError, match='waiting for the simulator'):
        source.prepare(['x', 'inet:127.0.0.1:0'])
    params.update({'anafi_sim/telemetry_bound_port': 70000, 'anafi_sim/telemetry_stream_id': 5})
    with pytest.raises(ValueError, match='telemetry_bound_port'):
        source.read()
    params['anafi_sim/telemetry_bound_port'] = 40000
    assert source.prepare(['x', 'inet:127.0.0.1:0']) == ['x', 'inet:127.0.0.1:40000']
    assert (source.port, source.stream_id) == (40000, 5)


class _Interface(object):
    """The interface node's reading path without ROS: supervisor -> parser -> core (expected id from the source)."""

    def __init__(self, source):
        self.source = source
        self.parser = TelemetryParser()
        self.core = GroundTruthInterface(publish_rate=100.0, stale_timeout=0.5)
        self.lock = threading.Lock()
        self.sup = ProcessSupervisor([sys.executable, LOGGER, '-r', '0', 'inet:127.0.0.1:0'], self.on_line,
                                     restart_timeout=1.0, backoff_initial=0.1, backoff_max=0.5,
                                     sample_timeout=1.0, prepare=self.prepare, on_event=self.on_event)

    def prepare(self, argv):
        argv = self.source.prepare(argv)
        with self.lock:
            self.core.expected_stream_id = self.source.stream_id
        return argv

    def on_event(self, kind, info):
        if kind == 'start':
            with self.lock:
                self.parser.reset()
                self.parser.stream_id = None

    def on_line(self, line, wall):
        with self.lock:
            s = self.parser.feed_line(line, line.endswith('\n'))
            if s is None:
                return False
            refused = self.core.foreign_samples
            self.core.on_sample(s, wall, self.parser.stream_id)
            return self.core.foreign_samples == refused


def _serve(server, stop, x):
    t = 0.0
    while not stop.is_set():
        t += 0.01
        server.publish(sample(t, x))
        time.sleep(0.01)


def _wait(predicate, timeout=15.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.02)
    return predicate()


def test_a_free_port_is_learnt_and_another_drones_stream_on_a_stale_port_is_refused_until_the_port_is_right():
    mine = TelemetryServer('127.0.0.1', 0, stream_id=new_stream_id())
    other = TelemetryServer('127.0.0.1', 0, stream_id=mine.stream_id % STREAM_ID_MAX + 1)
    stop = threading.Event()
    threads = []
    try:
        for server, x in ((mine, 1.0), (other, -7.0)):
            server.start()
            assert server.port > 0
            threads.append(threading.Thread(target=_serve, args=(server, stop, x), daemon=True))
            threads[-1].start()
        # the parameters point at the other simulator (a stale port): its stream is refused
        params = {'anafi_sim/telemetry_bound_port': other.port, 'anafi_sim/telemetry_stream_id': mine.stream_id}
        iface = _Interface(SimulatorSource('anafi_sim', params.get))
        iface.sup.start()
        try:
            assert _wait(lambda: iface.core.foreign_samples > 20)
            assert iface.core.published == 0
            health = iface.core.health(time.time())
            assert health.level == ERROR and 'another drone' in health.message, health.message
            # the simulator's real port: the supervisor restarts the refused stream, reads the port again
            params['anafi_sim/telemetry_bound_port'] = mine.port
            assert _wait(lambda: iface.core.published > 20)
            assert iface.core.last_timestamp is not None
            assert iface.sup.argv[-1] == 'inet:127.0.0.1:%d' % mine.port
            published = iface.core.published
            assert _wait(lambda: iface.core.published > published + 10)
            assert 'another drone' not in iface.core.health(time.time()).message
        finally:
            iface.sup.stop()
    finally:
        stop.set()
        for server in (mine, other):
            server.stop()

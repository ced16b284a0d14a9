"""anafi_sim.telemetry.server: the Sphinx-like TCP telemetry server and the tlm-data-logger stand-in (loopback)."""
import io
import os
import socket
import subprocess
import sys
import threading
import time

import pytest

from anafi_sim.telemetry.protocol import FIELDS, TelemetrySample, format_sample
from anafi_sim.telemetry.server import (BlockDecimator, TelemetryServer, block_timestamp, parse_endpoint,
                                        parse_logger_args, run_logger)
from conftest import ROOT

SCRIPT = os.path.join(ROOT, 'anafi_sim', 'scripts', 'tlm_data_logger.py')


def sample(t, x=1.25):
    values = dict((f, 0.0) for f in FIELDS)
    values.update(x=x, y=-2.5, z=7.0, yaw=0.5, timestamp=t, gimbal_pitch=-0.1)
    return TelemetrySample(**values)


def wait_for(predicate, timeout=5.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.005)
    return predicate()


@pytest.fixture
def server():
    srv = TelemetryServer('127.0.0.1', 0)
    srv.start()
    yield srv
    srv.stop()


class LoggerThread(object):
    """run_logger in a thread with in-memory stdout/stderr."""

    def __init__(self, argv):
        self.out = io.BytesIO()
        self.err = io.StringIO()
        self.code = None
        self.thread = threading.Thread(target=self._run, args=(argv,))
        self.thread.daemon = True
        self.thread.start()

    def _run(self, argv):
        self.code = run_logger(argv, self.out, self.err)

    def join(self):
        self.thread.join(10.0)
        assert not self.thread.is_alive(), 'logger did not exit'
        return self.code


def test_port_zero_binds_an_ephemeral_port(server):
    assert server.port > 0
    assert server.publish(sample(0.0)) == 0           # no clients: nothing to do, never blocks
    assert server.samples_published == 0


def test_logger_prints_every_block_unchanged_and_exits_0_when_server_stops(server):
    logger = LoggerThread(['inet:127.0.0.1:%d' % server.port])
    assert wait_for(lambda: server.client_count == 1)
    samples = [sample(k * 0.01, x=k) for k in range(50)]
    for s in samples:
        assert server.publish(s) == 1
    expected = ''.join(format_sample(s) + '\n' for s in samples).encode('ascii')
    assert wait_for(lambda: len(logger.out.getvalue()) >= len(expected))
    server.stop()
    assert logger.join() == 0
    assert logger.out.getvalue() == expected
    assert logger.err.getvalue() == ''


def test_rate_decimates_on_sample_timestamps(server):
    logger = LoggerThread(['-r', '100', 'inet:127.0.0.1:%d' % server.port])
    assert wait_for(lambda: server.client_count == 1)
    for k in range(100):                              # 100 Hz of sim time for 1 s
        server.publish(sample(k / 100.0))
    server.publish(sample(0.0))                       # simulator restart: printed, decimation restarts
    server.publish(sample(0.05))
    server.publish(sample(0.1))
    wait_for(lambda: logger.out.getvalue().count(b'timestamp') >= 12)
    server.stop()
    assert logger.join() == 0
    blocks = [b for b in logger.out.getvalue().split(b'\n\n') if b]
    stamps = [block_timestamp(b) for b in blocks]
    assert stamps == pytest.approx([k / 10.0 for k in range(10)] + [0.0, 0.1])


def test_cannot_connect_exits_1_with_message():
    probe = socket.socket()
    probe.bind(('127.0.0.1', 0))
    port = probe.getsockname()[1]
    probe.close()                                     # nothing listens there now
    out, err = io.BytesIO(), io.StringIO()
    assert run_logger(['inet:127.0.0.1:%d' % port], out, err) == 1
    assert 'cannot connect' in err.getvalue() and out.getvalue() == b''


def test_bad_arguments_exit_2():
    for argv in ([], ['tcp:127.0.0.1:9060'], ['inet:127.0.0.1'], ['inet:127.0.0.1:99999'],
                 ['-r', '-5', 'inet:127.0.0.1:9060'], ['-r', 'fast', 'inet:127.0.0.1:9060']):
        err = io.StringIO()
        assert run_logger(argv, io.BytesIO(), err) == 2, argv
        assert 'tlm_data_logger' in err.getvalue()


def test_argument_parsing():
    assert parse_logger_args(['-r', '4', 'inet:127.0.0.1:9060']) == (4.0, '127.0.0.1', 9060)
    assert parse_logger_args(['inet:localhost:1']) == (0.0, 'localhost', 1)
    assert parse_endpoint('inet:10.0.0.2:9061') == ('10.0.0.2', 9061)
    with pytest.raises(ValueError):
        parse_endpoint('inet::9060')


def test_block_helpers():
    block = format_sample(sample(12.345)).encode('ascii').rstrip(b'\n')
    assert block_timestamp(block) == pytest.approx(12.345)
    assert block_timestamp(b'foo : 1') is None
    assert block_timestamp(b'omniscient_anafi.timestamp : nan?') is None
    keep_all = BlockDecimator(0.0)
    assert keep_all.keep(b'x : 1') and keep_all.keep(b'x : 1')
    dec = BlockDecimator(0.25)
    kept = [dec.keep(b'a.timestamp : %g' % (k * 0.1)) for k in range(8)]
    assert kept == [True, False, False, True, False, False, True, False]
    assert dec.keep(b'no stamp here')                 # cannot decide: printed


def test_slow_client_is_dropped_without_blocking():
    srv = TelemetryServer('127.0.0.1', 0, max_backlog=4096)
    srv.start()
    try:
        lazy = socket.socket()
        lazy.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        lazy.connect(('127.0.0.1', srv.port))           # connects but never reads
        assert wait_for(lambda: srv.client_count == 1)
        for k in range(100000):
            srv.publish(sample(k * 0.01))
            if srv.clients_dropped_slow:
                break
        assert srv.clients_dropped_slow == 1 and srv.client_count == 0
        lazy.close()
    finally:
        srv.stop()


def test_closed_client_is_counted_and_removed(server):
    client = socket.create_connection(('127.0.0.1', server.port))
    assert wait_for(lambda: server.client_count == 1)
    client.close()
    for k in range(20):
        server.publish(sample(k * 0.01))
        if server.client_count == 0:
            break
        time.sleep(0.01)
    assert server.client_count == 0 and server.clients_disconnected == 1


def test_two_clients_get_the_same_stream(server):
    a = LoggerThread(['inet:127.0.0.1:%d' % server.port])
    b = LoggerThread(['-r', '0', 'inet:127.0.0.1:%d' % server.port])
    assert wait_for(lambda: server.client_count == 2)
    for k in range(10):
        assert server.publish(sample(k * 0.01)) == 2
    wait_for(lambda: a.out.getvalue().count(b'timestamp') == 10 and b.out.getvalue().count(b'timestamp') == 10)
    server.stop()
    assert a.join() == 0 and b.join() == 0
    assert a.out.getvalue() == b.out.getvalue() and a.out.getvalue().count(b'\n\n') == 10


def test_script_end_to_end(server):
    env = dict(os.environ)
    env['PYTHONPATH'] = ROOT + os.pathsep + env.get('PYTHONPATH', '')
    proc = subprocess.Popen([sys.executable, SCRIPT, '-r', '0', 'inet:127.0.0.1:%d' % server.port],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    try:
        assert wait_for(lambda: server.client_count == 1, timeout=10.0)
        for k in range(5):
            server.publish(sample(k * 0.01))
        time.sleep(0.2)
        server.stop()
        out, err = proc.communicate(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    assert out == ''.join(format_sample(sample(k * 0.01)) + '\n' for k in range(5)).encode('ascii')
    # and a refused connection exits 1 with a message
    bad = subprocess.run([sys.executable, SCRIPT, 'inet:127.0.0.1:%d' % server.port],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, timeout=10)
    assert bad.returncode == 1 and b'cannot connect' in bad.stderr

"""Property-based fuzzing (python3-hypothesis) of every core that takes outside input.

Bounded for CI: ``FUZZ_EXAMPLES`` examples per property (default 50; ``FUZZ_EXAMPLES=100000`` for a long
run), no deadline. Properties: nothing raises, nothing non-finite comes out, and every rejected input is
counted (the counters grow). Cores: the telemetry parser, the interface core (GroundTruthInterface) and the
supervisor's capped line reader, the reference-log reader, the controller contract's InputGate /
its flight envelope (anafi_control.envelope), and the MPC and PID controllers through ``Controller.cycle``.
"""
import io
import math
import os
import tempfile
import types

import pytest

hypothesis = pytest.importorskip('hypothesis')
from hypothesis import HealthCheck, given, settings, strategies as st  # noqa: E402

from anafi_control import contract  # noqa: E402
from anafi_control.mpc_tracking import MpcTracking  # noqa: E402
from anafi_control.pid_framework import PidTracking  # noqa: E402
from anafi_sim.mission import reference_log  # noqa: E402
from anafi_sim.interface import ground_truth as gt  # noqa: E402
from anafi_sim.interface.supervisor import ProcessSupervisor  # noqa: E402
from anafi_sim.telemetry import protocol  # noqa: E402

EXAMPLES = int(os.environ.get('FUZZ_EXAMPLES', '50'))


def fuzz(n=EXAMPLES):
    """Settings of one property: ``n`` examples, no deadline, no database (CI runs stay reproducible)."""
    return settings(max_examples=n, deadline=None, database=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])


# any float, including NaN, +-inf, huge and subnormal values
any_float = st.floats(allow_nan=True, allow_infinity=True, width=64)
finite = st.floats(allow_nan=False, allow_infinity=False)
KEYS = list(protocol.key_map().keys())


def _value_text():
    return st.one_of(
        st.builds(repr, any_float),
        st.sampled_from(['1_000', '\u0661\u0662', '1e', '--1', '0x10', ' ', '', 'nan', '-inf', '1e400',
                         '\u00a01.0', '１２']),
        st.text(max_size=12))


telemetry_line = st.one_of(
    st.builds(lambda k, v, sep: '%s%s%s\n' % (k, sep, v), st.sampled_from(KEYS), _value_text(),
              st.sampled_from([' : ', ':', ' :', '\t:\t', ': '])),
    st.text(max_size=80),
    st.builds(lambda b: b.decode('utf-8', 'replace'), st.binary(max_size=80)),
)


def _parser_consistent(parser, n_lines, samples):
    c = parser.counters
    assert c['lines'] == n_lines
    assert c['samples'] == len(samples)
    # every line is counted once: blank, malformed, nonfinite, unknown key, or a value kept
    assert c['blank'] + c['malformed'] + c['nonfinite'] + c['unknown_key'] <= n_lines
    for s in samples:
        assert all(math.isfinite(v) for v in s)


@fuzz()
@given(st.lists(telemetry_line, max_size=60))
def test_parser_never_raises_and_only_emits_finite_samples(lines):
    parser = protocol.TelemetryParser()
    samples = []
    for line in lines:
        out = parser.feed_line(line, complete=line.endswith('\n'))
        if out is not None:
            samples.append(out)
    _parser_consistent(parser, len(lines), samples)


@fuzz()
@given(st.lists(st.tuples(st.sampled_from(KEYS), any_float), min_size=1, max_size=80))
def test_parser_counts_every_non_finite_value_and_emits_the_finite_ones(pairs):
    parser = protocol.TelemetryParser()
    samples = [s for s in (parser.feed_line('%s : %r\n' % (k, v)) for k, v in pairs) if s is not None]
    bad = sum(1 for _, v in pairs if not math.isfinite(v))
    assert parser.nonfinite == bad
    assert parser.malformed == 0 and parser.unknown_key == 0
    _parser_consistent(parser, len(pairs), samples)


@fuzz()
@given(st.sampled_from(KEYS), st.sampled_from(['1_000', '\u0661', '１', '1.0\u00a0', '\u20281', '0x1p3', 'inf_']))
def test_parser_rejects_non_ascii_and_underscore_numbers(key, text):
    parser = protocol.TelemetryParser()
    assert parser.feed_line('%s : %s\n' % (key, text)) is None
    assert parser.malformed + parser.nonfinite == 1


sample_values = st.lists(any_float, min_size=len(protocol.FIELDS), max_size=len(protocol.FIELDS))


@fuzz()
@given(st.lists(st.tuples(sample_values, finite), max_size=40))
def test_interface_core_publishes_only_finite_samples_and_counts_rejects(items):
    core = gt.GroundTruthInterface()
    nonfinite = 0
    wall = 1000.0
    for values, dt in items:
        wall += abs(dt) % 1.0
        sample = protocol.TelemetrySample._make(values)
        if not all(math.isfinite(v) for v in values):
            nonfinite += 1
        out = core.on_sample(sample, wall)
        if out is not None:
            assert all(math.isfinite(v) for v in out)
    assert core.rejected_nonfinite == nonfinite
    assert core.received == len(items)
    assert (core.published + core.decimated + core.duplicates + core.rejected_nonfinite
            + core.rejected_beyond_bounds) == len(items)
    health = core.health(wall, protocol.TelemetryParser().counters, {'running': True, 'restarts': 0})
    assert health.level in (gt.OK, gt.WARN, gt.ERROR)
    if nonfinite and core.published:
        assert health.level != gt.OK


# a chunk: some random bytes, or a run of one byte up to 3x the cap (cheap to generate), with or without newline
chunk = st.one_of(st.binary(max_size=100),
                  st.builds(lambda b, n, nl: b * n + (b'\n' if nl else b''),
                            st.sampled_from([b'a', b'\xff', b'\r', b'\x00', b'7']), st.integers(0, 9000),
                            st.booleans()))


@fuzz(max(20, EXAMPLES // 2))
@given(st.lists(chunk, max_size=8))
def test_supervisor_line_reader_caps_lines_and_counts_the_dropped_ones(chunks):
    data = b''.join(chunks)
    got = []
    sup = ProcessSupervisor(['true'], lambda line, t: got.append(line) or False, max_line=4096)
    sup._read_stdout(types.SimpleNamespace(stdout=io.BufferedReader(io.BytesIO(data))))
    lines = data.split(b'\n')
    if lines and lines[-1] == b'':
        lines.pop()
    complete = data.count(b'\n')
    oversize = sum(1 for i, ln in enumerate(lines) if len(ln) + (1 if i < complete else 0) > 4096)
    assert sup.oversize_lines == oversize
    assert sup.lines == len(got) == len(lines) - oversize
    assert all(len(line.encode('utf-8')) <= 3 * 4096 for line in got)   # decoded with 'replace'


class _Chunks(io.RawIOBase):
    """A pipe whose reads return the given chunks one by one (cut anywhere), behind a BufferedReader."""

    def __init__(self, chunks):
        self._chunks = [c for c in chunks if c]

    def readable(self):
        return True

    def readinto(self, buffer):
        if not self._chunks:
            return 0
        chunk = self._chunks[0][:len(buffer)]
        self._chunks[0] = self._chunks[0][len(chunk):]
        if not self._chunks[0]:
            self._chunks.pop(0)
        buffer[:len(chunk)] = chunk
        return len(chunk)


@fuzz(max(20, EXAMPLES // 2))
@given(st.lists(chunk, max_size=8), st.lists(st.integers(min_value=1, max_value=6000), max_size=12))
def test_supervisor_line_reader_gives_the_same_lines_however_the_reads_cut_them(chunks, cuts):
    data = b''.join(chunks)
    whole, pieces = [], []
    one = ProcessSupervisor(['true'], lambda line, t: whole.append(line) or False, max_line=4096)
    one._read_stdout(types.SimpleNamespace(stdout=io.BufferedReader(_Chunks([data]))))
    reads, at = [], 0
    for size in cuts:
        reads.append(data[at:at + size])
        at += size
    reads.append(data[at:])
    cut = ProcessSupervisor(['true'], lambda line, t: pieces.append(line) or False, max_line=4096)
    cut._read_stdout(types.SimpleNamespace(stdout=io.BufferedReader(_Chunks(reads))))
    assert pieces == whole
    assert (cut.lines, cut.oversize_lines) == (one.lines, one.oversize_lines)


def _csv_cell():
    return st.one_of(st.builds(repr, any_float), st.text(max_size=6), st.just(''))


@fuzz(max(20, EXAMPLES // 4))
@given(st.lists(st.lists(_csv_cell(), min_size=0, max_size=len(reference_log.COLUMNS) + 2), max_size=15),
       st.booleans())
def test_reference_log_reader_never_raises_on_any_rows(rows, shuffled):
    header = list(reference_log.COLUMNS)
    if shuffled:
        header.reverse()
    fd, path = tempfile.mkstemp(suffix='.csv')
    try:
        with os.fdopen(fd, 'w') as f:
            f.write(','.join(header) + '\n')
            for row in rows:
                f.write(','.join(c.replace(',', ' ').replace('\n', ' ').replace('\r', ' ').replace('"', '')
                                 for c in row) + '\n')
        log = reference_log.read_log(path)
    finally:
        os.unlink(path)
    assert len(log) + len(log.parse_errors) == len(rows)
    garbage = reference_log.detect_garbage(log)
    assert garbage.summary() is not None


@fuzz(max(20, EXAMPLES // 4))
@given(st.text(max_size=300))
def test_reference_log_reader_raises_only_value_error_on_a_bad_header(text):
    fd, path = tempfile.mkstemp(suffix='.csv')
    try:
        with os.fdopen(fd, 'w', encoding='utf-8', errors='replace') as f:
            f.write(text)
        try:
            reference_log.read_log(path)
        except ValueError:
            pass
    finally:
        os.unlink(path)


# --------------------------------------------------------------------- controller contract
vec3 = st.tuples(any_float, any_float, any_float)
quat = st.one_of(st.tuples(any_float, any_float, any_float, any_float), st.just((0.0, 0.0, 0.0, 1.0)))
waypoint = st.one_of(
    st.tuples(*[any_float] * 7),
    st.tuples(*([st.floats(-300, 300)] * 2 + [st.floats(-5, 80)] + [st.floats(-20, 20)] * 3
                + [st.floats(-720, 720)])),
    st.lists(st.one_of(any_float, st.text(max_size=3), st.none()), max_size=9))
event = st.one_of(
    st.tuples(st.just('state'), st.floats(-0.5, 2.0), vec3, quat, vec3),
    st.tuples(st.just('waypoint'), st.floats(-0.5, 2.0), waypoint),
    st.tuples(st.just('cycle'), st.one_of(st.floats(-0.5, 2.0), any_float)))


def _run_events(controller, events):
    t = 0.0
    commands = 0
    for ev in events:
        kind, dt = ev[0], ev[1]
        t_ev = t + dt if math.isfinite(dt) else dt
        if math.isfinite(t_ev):
            t = max(t, t_ev)
        if kind == 'state':
            before = controller.counters['rejected_states']
            if not controller.on_state(t_ev, ev[2], ev[3], ev[4]):
                assert controller.counters['rejected_states'] == before + 1
        elif kind == 'waypoint':
            before = controller.counters['rejected_waypoints']
            if not controller.on_waypoint(t_ev, ev[2]):
                assert controller.counters['rejected_waypoints'] == before + 1
        else:
            out = controller.cycle(t_ev)
            assert out.key in contract.TRACKING + contract.HOVER_KEYS
            if out.command is not None:
                commands += 1
                assert len(out.command) == 4 and all(math.isfinite(v) for v in out.command), out
                if not out.ok:
                    assert contract.failsafe(out.key) == contract.HOLD, out
            elif not out.ok and contract.failsafe(out.key) == contract.HOLD:
                # a hold starts from reset loops: the PID framework warms up for one computation
                assert out.result is not None, out
    c = controller.counters
    assert c['cycles'] == c[contract.OK] + c['hover'] and c[contract.LIMITING] <= c[contract.OK]
    assert c['hover'] == c[contract.HOLD] + c[contract.SILENT]
    return commands


def _flying_start(controller):
    """A good state and waypoint so that the fuzzed events hit a controller that is tracking."""
    controller.on_state(0.0, (0.0, 0.0, 5.0), (0.0, 0.0, 0.0, 1.0), (1.0, 0.0, 0.0))
    controller.on_waypoint(0.0, (2.0, 0.0, 5.0, 1.0, 0.0, 0.0, 0.0))
    assert controller.cycle(0.01).key == contract.OK


@fuzz()
@given(st.lists(event, max_size=40))
def test_input_gate_never_raises_and_counts_rejects(events):
    gate = contract.InputGate(state_timeout=0.5, waypoint_timeout=1.0)
    t = 0.0
    for ev in events:
        t += ev[1] if math.isfinite(ev[1]) else 0.0
        if ev[0] == 'state':
            before = gate.counters['rejected_states']
            ok = gate.on_state(t, ev[2], ev[3], ev[4])
            assert ok or gate.counters['rejected_states'] == before + 1
            if not all(math.isfinite(v) for v in ev[2] + ev[3] + ev[4]):
                assert not ok
        elif ev[0] == 'waypoint':
            before = gate.counters['rejected_waypoints']
            ok = gate.on_waypoint(t, ev[2])
            assert ok or gate.counters['rejected_waypoints'] == before + 1
            if ok:
                wp = gate.waypoint.value
                assert len(wp) == 7 and all(math.isfinite(v) for v in wp)
        else:
            inputs, key, reason = gate.check(ev[1])
            gate.count_cycle(key)
            if key in contract.TRACKING or contract.failsafe(key) == contract.HOLD:
                assert all(math.isfinite(v) for v in inputs.pos + inputs.vel + (inputs.yaw,) + inputs.waypoint)
                assert gate.envelope.inside(inputs.waypoint, gate.centre, tolerance=1e-6 * (1 + abs(
                    gate.envelope.geofence_radius)))
            else:
                assert inputs is None


# |v| < 1e150 here; huge finite values: the reproducer below
moderate = st.floats(-1e150, 1e150)


@fuzz()
@given(st.tuples(*[moderate] * 3), st.one_of(st.none(), st.tuples(moderate, moderate)),
       st.one_of(st.none(), st.tuples(moderate, moderate, moderate)))
def test_the_envelope_never_raises_and_keeps_the_target_in_the_fence(wp, centre, drone):
    env = contract.Envelope()
    out, notes = env.limit_waypoint(wp + (0.0, 0.0, 0.0, 0.0), centre, drone)
    assert all(math.isfinite(v) for v in out)
    assert set(n for n, _ in notes) <= set(('geofence', 'reach', 'fence_braking'))
    assert env.inside(out, centre, tolerance=1e-9 * (1.0 + (abs(centre[0]) + abs(centre[1]) if centre else 0.0)))


# found by fuzzing: the distance to the drone once overflowed (sqrt of squares) for a finite but
# huge state; now math.hypot, and the target is clipped into the fence first
def test_a_huge_finite_state_then_a_waypoint_is_limited_not_raised():
    gate = contract.InputGate()
    assert gate.on_state(0.0, (0.0, 0.0, 5.0), (0.0, 0.0, 0.0, 1.0), (0.0, 0.0, 0.0))
    assert gate.on_state(0.1, (1e155, 0.0, 5.0), (0.0, 0.0, 0.0, 1.0), (0.0, 0.0, 0.0))   # finite: accepted
    assert gate.on_waypoint(0.1, (0.0, 0.0, 5.0, 0.0, 0.0, 0.0, 0.0))                    # no OverflowError
    inputs, key, _ = gate.check(0.1)
    assert key == contract.LIMITING and gate.envelope.inside(inputs.waypoint, gate.centre)


@fuzz(max(10, EXAMPLES // 5))
@given(st.lists(event, max_size=20))
def test_mpc_cycle_never_raises_nor_commands_non_finite(events):
    mpc = MpcTracking()
    _flying_start(mpc)
    _run_events(mpc, events)


@fuzz(max(25, EXAMPLES // 2))
@given(st.lists(event, max_size=40))
def test_pid_cycle_never_raises_nor_commands_non_finite(events):
    pid = PidTracking()
    _flying_start(pid)
    _run_events(pid, events)


@fuzz(max(10, EXAMPLES // 5))
@given(st.tuples(*[st.one_of(st.floats(-1e9, 1e9), st.sampled_from([1e300, -1e300, 5e-324]))] * 3),
       st.tuples(*[st.one_of(st.floats(-1e6, 1e6), st.sampled_from([1e300, -1e300]))] * 3),
       st.sampled_from([MpcTracking, PidTracking]))
def test_extreme_but_finite_state_gives_a_finite_command_or_nothing(pos, vel, cls):
    ctl = cls()
    ctl.on_state(0.0, (0.0, 0.0, 5.0), (0.0, 0.0, 0.0, 1.0), (0.0, 0.0, 0.0))
    ctl.on_waypoint(0.0, (1.0, 0.0, 5.0, 0.0, 0.0, 0.0, 0.0))
    for i in range(1, 4):
        ctl.on_state(0.1 * i, pos, (0.0, 0.0, 0.0, 1.0), vel)
        out = ctl.cycle(0.1 * i)
        assert out.command is None or all(math.isfinite(v) for v in out.command), out

"""TelemetryParser: tlm-data-logger lines -> TelemetrySample, incl. every bad-input case."""
import math

import pytest

from anafi_sim.telemetry.protocol import (COUNTER_NAMES, DEFAULT_PREFIX, FIELDS, TelemetryParser, TelemetrySample,
                                 format_sample, key_map)


def make_sample(base=0.0):
    return TelemetrySample(*[base + 0.25 * i - 1.5 for i in range(len(FIELDS))])


def lines_of(sample, prefix=DEFAULT_PREFIX):
    return format_sample(sample, prefix).splitlines(True)


def feed_all(parser, lines):
    return [s for s in (parser.feed_line(line) for line in lines) if s is not None]


def counts(parser, **expected):
    """Counters with every unnamed counter expected to be 0 except lines/samples."""
    got = parser.counters
    for name in COUNTER_NAMES:
        if name in ('lines', 'samples'):
            continue
        assert got[name] == expected.get(name, 0), (name, got)


def test_round_trip_of_format_sample():
    parser = TelemetryParser()
    s1, s2 = make_sample(0.0), make_sample(10.0)
    out = feed_all(parser, lines_of(s1) + lines_of(s2))
    assert out == [s1, s2]
    assert parser.counters['samples'] == 2
    assert parser.counters['lines'] == 2 * len(FIELDS)
    counts(parser)


def test_sample_is_emitted_on_its_last_key_not_on_the_next_sample():
    parser = TelemetryParser()
    lines = lines_of(make_sample())
    for line in lines[:-1]:
        assert parser.feed_line(line) is None
    assert parser.feed_line(lines[-1]) == make_sample()


def test_key_order_does_not_matter():
    parser = TelemetryParser()
    lines = lines_of(make_sample())
    out = feed_all(parser, list(reversed(lines)))
    assert out == [make_sample()]


def test_values_are_read_exactly():
    parser = TelemetryParser()
    lines = ['%s : %r\n' % (k, -0.1 * i) for i, k in enumerate(key_map())]
    (sample,) = feed_all(parser, lines)
    assert sample.x == 0.0 and sample.y == -0.1 and sample.gimbal_pitch == -0.1 * (len(FIELDS) - 1)
    assert sample.timestamp == -0.1 * FIELDS.index('timestamp')


def test_blank_lines_are_counted_and_ignored():
    parser = TelemetryParser()
    lines = lines_of(make_sample())
    lines[3:3] = ['\n', '   \t \n', '']
    assert feed_all(parser, lines) == [make_sample()]
    counts(parser, blank=3)


@pytest.mark.parametrize('bad', [
    'omniscient_anafi.worldPosition.x 1.0\n',       # no colon
    '==== sample 12 ====\n',                          # decoration line
    'omniscient_anafi.worldPosition.x : abc\n',     # not a number
    'omniscient_anafi.worldPosition.x : \n',         # value missing
    'omniscient_anafi.worldPosition.x : 1.0 2.0\n',  # two numbers
    'omniscient_anafi.worldPosition.x : 0x1p3\n',    # not a decimal number
    'omniscient_anafi.worldPos',                      # cut in the key
    'omniscient_anafi.worldPosition.x : 1.2.3\n',
    'omniscient_anafi.worldPosition.x : 1_000\n',                 # Python literal syntax, not a number here
    'omniscient_anafi.worldPosition.x : 1_0.5e1_0\n',
    'omniscient_anafi.worldPosition.x : \u0661\u0662\n',           # Arabic-Indic digits (float() takes them)
    'omniscient_anafi.worldPosition.x : \uff11.5\n',               # full-width digit one
    'omniscient_anafi.worldPosition.x : 1.5\u2003\n',              # non-ASCII white space
])
def test_malformed_lines_are_counted_and_ignored(bad):
    parser = TelemetryParser()
    lines = lines_of(make_sample())
    lines.insert(5, bad)
    assert feed_all(parser, lines) == [make_sample()]
    counts(parser, malformed=1)


@pytest.mark.parametrize('text, value', [('1', 1.0), ('-2.5', -2.5), ('+.5', 0.5), ('3.', 3.0), ('1e3', 1000.0),
                                         ('-1.25E-2', -0.0125), ('  7.0\t', 7.0)])
def test_ascii_decimal_and_exponent_forms_are_accepted(text, value):
    parser = TelemetryParser(required_fields=('x',))
    sample = parser.feed_line('omniscient_anafi.worldPosition.x : %s\n' % text)
    assert sample is not None and sample.x == value


def test_partial_last_line_is_malformed_even_if_it_parses():
    parser = TelemetryParser()
    lines = lines_of(make_sample())
    assert parser.feed_line(lines[0].rstrip('\n')[:-2], complete=False) is None
    assert parser.counters['malformed'] == 1
    # the cut value was not taken: the sample still completes with the full line
    assert feed_all(parser, lines) == [make_sample()]
    counts(parser, malformed=1)


@pytest.mark.parametrize('value', ['nan', 'NaN', 'inf', '-inf', 'Infinity', '1e999'])
def test_nonfinite_values_are_ignored_and_the_sample_is_not_completed_with_them(value):
    parser = TelemetryParser()
    s1, s2 = make_sample(0.0), make_sample(5.0)
    lines = lines_of(s1)
    bad = lines[2].split(':')[0] + ': ' + value + '\n'
    out = feed_all(parser, lines[:2] + [bad] + lines[3:] + lines_of(s2))
    # the first sample never got a finite y: it is dropped (as partial) when the second starts
    assert out == [s2]
    counts(parser, nonfinite=1, partial_samples=1)


def test_nonfinite_value_followed_by_a_good_one_completes_the_sample():
    parser = TelemetryParser()
    lines = lines_of(make_sample())
    bad = lines[0].split(':')[0] + ': nan\n'
    assert feed_all(parser, [bad] + lines) == [make_sample()]
    counts(parser, nonfinite=1)


def test_unknown_keys_are_counted_and_ignored():
    parser = TelemetryParser()
    lines = lines_of(make_sample())
    extra = ['omniscient_anafi.batteryLevel : 0.9\n', 'other_drone.worldPosition.x : 3.0\n',
             'worldPosition.x : 1.0\n', 'gimbal_yaw_anafi.motor_angle : 0.1\n']
    lines[4:4] = extra
    assert feed_all(parser, lines) == [make_sample()]
    counts(parser, unknown_key=len(extra))


def test_repeated_key_drops_the_partial_sample_and_restarts_with_that_key():
    parser = TelemetryParser()
    s1, s2 = make_sample(0.0), make_sample(7.0)
    # first sample cut after 10 lines, then a full second sample starting again with key 0
    out = feed_all(parser, lines_of(s1)[:10] + lines_of(s2))
    assert out == [s2]
    counts(parser, partial_samples=1)
    # the repeated key starts the new sample: a sample that restarts at key 3 completes with keys 0..2 after
    parser = TelemetryParser()
    l1, l2 = lines_of(s1), lines_of(s2)
    out = feed_all(parser, l1[:5] + l2[3:] + l2[:3])
    assert out == [s2]
    counts(parser, partial_samples=1)


def test_values_do_not_leak_from_a_dropped_partial_sample():
    parser = TelemetryParser()
    s1, s2 = make_sample(0.0), make_sample(7.0)
    # s1 lines 0..9, then s2 from line 5 on (key 5 repeats) -> keys 0..4 must come from s2, not s1
    assert feed_all(parser, lines_of(s1)[:10] + lines_of(s2)[5:]) == []
    assert feed_all(parser, lines_of(s2)[:5]) == [s2]


def test_extra_spaces_tabs_and_decorations_are_tolerated():
    parser = TelemetryParser()
    sample = make_sample()
    lines = []
    for i, (key, field) in enumerate(key_map().items()):
        value = getattr(sample, field)
        fmt = ['  %s   :   %r   \r\n', '\t%s\t:\t%r\n', '%s:%r\n', '[12:00:01] %s : %r\n', '| %s : %r\n'][i % 5]
        lines.append(fmt % (key, value))
    assert feed_all(parser, lines) == [sample]
    counts(parser)


def test_a_different_prefix():
    parser = TelemetryParser(prefix='omniscient_bebop2.')
    sample = make_sample()
    assert feed_all(parser, lines_of(sample, prefix=DEFAULT_PREFIX)) == []
    assert parser.counters['unknown_key'] == len(FIELDS) - 2  # gimbal keys have no prefix
    assert feed_all(parser, lines_of(sample, prefix='omniscient_bebop2.')) == [sample]


def test_required_fields_subset_completes_without_the_others():
    parser = TelemetryParser(required_fields=[f for f in FIELDS if not f.startswith('gimbal')])
    sample = make_sample()
    lines = [line for line in lines_of(sample) if not line.startswith('gimbal')]
    (out,) = feed_all(parser, lines)
    assert out.gimbal_roll == 0.0 and out.gimbal_pitch == 0.0 and out.x == sample.x
    # optional fields keep their last value and never trigger a partial sample
    parser.feed_line('gimbal_pitch_anafi.motor_angle : -0.5\n')
    parser.feed_line('gimbal_pitch_anafi.motor_angle : -0.7\n')
    (out,) = feed_all(parser, lines)
    assert out.gimbal_pitch == -0.7
    counts(parser)


def test_bad_required_fields_raise():
    with pytest.raises(ValueError):
        TelemetryParser(required_fields=['x', 'altitude'])
    with pytest.raises(ValueError):
        TelemetryParser(required_fields=[])


def test_reset_drops_and_counts_the_pending_sample():
    parser = TelemetryParser()
    parser.reset()
    assert parser.counters['partial_samples'] == 0
    lines = lines_of(make_sample())
    feed_all(parser, lines[:7])
    parser.reset()
    assert parser.counters['partial_samples'] == 1
    assert feed_all(parser, lines[7:]) == []
    assert feed_all(parser, lines[:7]) == [make_sample()]


def test_counters_add_up_on_a_messy_stream():
    parser = TelemetryParser()
    good = [make_sample(float(i)) for i in range(3)]
    stream = (['garbage\n', '\n'] + lines_of(good[0]) + ['x.y : nan\n', 'foo : 1\n'] + lines_of(good[1])[:4]
              + lines_of(good[2]))
    out = feed_all(parser, stream)
    assert out == [good[0], good[2]]
    c = parser.counters
    assert c['lines'] == len(stream)
    assert c == dict(lines=len(stream), samples=2, blank=1, malformed=1, nonfinite=0, unknown_key=2,
                     partial_samples=1)
    assert parser.errors == 2
    assert not any(math.isnan(v) for s in out for v in s)

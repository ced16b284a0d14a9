"""bench_interface.py part ``parser``: lines/s of TelemetryParser.feed_line next to a naive regex parser.

The lines are what the CLI prints (``format_sample`` of a simulated flight, blank line between samples);
both parsers are first checked to return exactly the formatted samples, then timed in alternating rounds
so background load hits both alike.
"""
import math
import re
import time

from anafi_sim.telemetry.protocol import FIELDS, TelemetryParser, TelemetrySample, format_sample, key_map
from interface_samples import flight_samples, rounded


class NaiveRegexParser(object):
    """What one would write first: a regex per line, a dict of values, a sample when all keys are in."""

    LINE = re.compile(r'^\s*(\S+)\s*:\s*(\S+)\s*$')

    def __init__(self, prefix='omniscient_anafi.'):
        self.fields = key_map(prefix)
        self.values = {}
        self.samples = 0

    def feed_line(self, line):
        m = self.LINE.match(line)
        if m is None:
            return None
        field = self.fields.get(m.group(1))
        if field is None:
            return None
        try:
            value = float(m.group(2))
        except ValueError:
            return None
        if not math.isfinite(value):
            return None
        self.values[field] = value
        if len(self.values) < len(FIELDS):
            return None
        sample = TelemetrySample(**self.values)
        self.values = {}
        self.samples += 1
        return sample


def _parse_all(parser, lines):
    feed = parser.feed_line
    n = 0
    for line in lines:
        if feed(line) is not None:
            n += 1
    return n


def bench_parser(n_samples=2000, rounds=9, target_s=0.3):
    samples = flight_samples(n_samples)
    text = ''.join(format_sample(s) + '\n' for s in samples)  # the server's blocks, printed unchanged by the CLI
    lines = text.splitlines(True)
    # correctness first: both give the same samples
    ours = [s for s in map(TelemetryParser().feed_line, lines) if s is not None]
    naive_p = NaiveRegexParser()
    naive = [s for s in map(naive_p.feed_line, lines) if s is not None]
    expected = [TelemetrySample(*[rounded(v) for v in s]) for s in samples]
    if ours != expected or naive != expected:
        raise RuntimeError('parsers disagree with the formatted samples (ours ok: %s, naive ok: %s)'
                           % (ours == expected, naive == expected))
    t0 = time.perf_counter()
    _parse_all(TelemetryParser(), lines)
    reps = max(1, int(round(target_s / max(time.perf_counter() - t0, 1e-6))))
    work = lines * reps
    rates = {'ours': [], 'naive': []}
    for _ in range(rounds):  # alternate, so background load hits both alike
        for name, make in (('ours', TelemetryParser), ('naive', NaiveRegexParser)):
            parser = make()
            t0 = time.perf_counter()
            got = _parse_all(parser, work)
            elapsed = time.perf_counter() - t0
            if got != n_samples * reps:
                raise RuntimeError('%s parser returned %d samples, expected %d' % (name, got, n_samples * reps))
            rates[name].append(len(work) / elapsed)
    return {'lines_per_sample': len(lines) / float(n_samples), 'n_lines': len(work), 'rounds': rounds,
            'ours': rates['ours'], 'naive': rates['naive']}

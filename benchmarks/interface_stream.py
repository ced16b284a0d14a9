"""bench_interface.py's live stream: samples fed to a TelemetryServer at a wall-clock rate, the DroneData
messages received back, and their latency, rate and consistency.

``Feeder`` publishes the samples stamped with their wall time of generation (minus a whole-second epoch,
so the 9 printed digits resolve <= 10 us); ``Recorder`` keeps (receipt wall time, message);
``analyse`` pairs each message with the sample its timeStamp names.
"""
import threading
import time

import numpy as np

from anafi_sim.interface.ground_truth import GroundTruthInterface
from anafi_sim.telemetry.protocol import FIELDS, TelemetrySample
from interface_samples import rounded
from paper_interface import MSG_FIELDS


class Feeder(object):
    """Publishes the samples on the server at ``rate`` Hz of wall time, stamped with their generation time."""

    def __init__(self, server, samples, rate, epoch):
        self.server = server
        self.samples = samples
        self.period = 1.0 / rate
        self.epoch = epoch
        self.sent = {}      # rounded timestamp -> rounded sample (what the interface must publish)
        self.times = []     # generation wall times
        self.lateness = []  # behind schedule at each tick [s]
        self.late = 0       # ticks more than 2 ms behind schedule
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name='feeder', daemon=True)

    def start(self):
        self._thread.start()

    def stop(self):
        self._stop.set()
        self._thread.join(2.0)

    def _run(self):
        i = 0
        n = len(self.samples)
        due = time.monotonic()
        while not self._stop.is_set():
            now = time.monotonic()
            if now < due:
                self._stop.wait(due - now)
                continue
            if now - due > 0.002:
                self.late += 1
            if now - due > 0.5:  # badly stalled: resynchronise instead of bursting
                due = now
            wall = time.time()
            self.lateness.append(now - due)
            sample = self.samples[i % n]._replace(timestamp=wall - self.epoch)
            key = rounded(sample.timestamp)
            self.sent[key] = TelemetrySample(*[rounded(v) for v in sample])
            self.times.append(wall)
            self.server.publish(sample)
            i += 1
            due += self.period


class Recorder(object):
    """Subscriber callback storing (receipt wall time, message)."""

    def __init__(self):
        self.rx = []

    def __call__(self, msg):
        self.rx.append((time.time(), msg))

    def count_since(self, t):
        return sum(1 for r, _ in self.rx[-500:] if r >= t)


def analyse(rx, t0, t1, feeder):
    """Latency / rate / consistency of the messages received in [t0, t1]."""
    epoch = feeder.epoch
    pub, recv, stamps = [], [], []
    torn = unknown = 0
    for r, msg in rx:
        if not t0 <= r <= t1:
            continue
        gen = epoch + msg.timeStamp
        pub.append(msg.header.stamp.to_sec() - gen)
        recv.append(r - gen)
        stamps.append(msg.timeStamp)
        sent = feeder.sent.get(msg.timeStamp)
        if sent is None:
            unknown += 1
        elif any(getattr(msg, MSG_FIELDS[f]) != getattr(sent, f) for f in FIELDS):
            torn += 1
    generated = sum(1 for w in feeder.times if t0 <= w <= t1)
    late = [lt for w, lt in zip(feeder.times, feeder.lateness) if t0 <= w <= t1]
    # What the interface's own rate limiter (on sample timestamps) lets through of the generated stream:
    # a feeder tick that comes late bunches timestamps, and the limiter rightly drops the too-close ones.
    limiter = GroundTruthInterface(publish_rate=1.0 / feeder.period)
    publishable = 0
    for ts, sample in list(feeder.sent.items()):
        if limiter.on_sample(sample, feeder.epoch + ts) is not None and t0 <= feeder.epoch + ts <= t1:
            publishable += 1
    n = len(recv)

    def pct(values):
        a = np.array(values) * 1e3
        return dict(p50=np.percentile(a, 50), p95=np.percentile(a, 95), p99=np.percentile(a, 99),
                    max=a.max(), n=len(a)) if len(a) else None
    return dict(n=n, rate=n / (t1 - t0), generated=generated, gen_rate=generated / (t1 - t0),
                publishable=publishable, late2ms=sum(1 for lt in late if lt > 0.002),
                late_p99=1e3 * np.percentile(late, 99) if late else float('nan'),
                distinct=len(set(stamps)), torn=torn, unknown=unknown, pub=pct(pub), recv=pct(recv))

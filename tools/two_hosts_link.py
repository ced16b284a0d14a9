#!/usr/bin/env python3
"""A user-space network link between two network namespaces, with delay and loss: netem's job where the
kernel has no sch_netem (tools/two_hosts.sh --userspace-link DELAY_MS,LOSS_PCT).

    two_hosts_link.py NS_A IF_A NS_B IF_B [--delay-ms 5] [--loss-pct 1] [--seed 0] [--ready-file PATH]

Opens a TUN device IF_A inside namespace NS_A and IF_B inside NS_B (setns(2) on /var/run/netns/NS, so the
devices live only there), then copies every IP packet read from one to the other, dropping each with
probability LOSS_PCT / 100 and delivering it DELAY_MS later (per direction, like `netem delay D loss L` on
both ends of a veth pair). The caller gives the devices their addresses (they exist while this runs;
touches --ready-file once they do). Stops on SIGINT/SIGTERM; prints the packet counts. Linux, root only.
The copying costs some CPU and ~0.1 ms per packet: compare with --delay-ms 0 --loss-pct 0 (the link alone).
"""
import argparse
import ctypes
import fcntl
import heapq
import os
import random
import select
import signal
import struct
import sys
import time

CLONE_NEWNET = 0x40000000
TUNSETIFF = 0x400454ca
IFF_TUN = 0x0001
IFF_NO_PI = 0x1000
MTU = 65536


def open_tun_in(netns, ifname):
    """fd of a new TUN device ``ifname`` created inside network namespace ``netns`` (by name)."""
    libc = ctypes.CDLL(None, use_errno=True)
    own = os.open('/proc/self/ns/net', os.O_RDONLY)
    target = os.open(os.path.join('/var/run/netns', netns), os.O_RDONLY)
    try:
        if libc.setns(target, CLONE_NEWNET) != 0:
            raise OSError(ctypes.get_errno(), 'setns into %s' % netns)
        try:
            fd = os.open('/dev/net/tun', os.O_RDWR)
            fcntl.ioctl(fd, TUNSETIFF, struct.pack('16sH', ifname.encode(), IFF_TUN | IFF_NO_PI))
        finally:
            if libc.setns(own, CLONE_NEWNET) != 0:
                raise OSError(ctypes.get_errno(), 'setns back')
    finally:
        os.close(own)
        os.close(target)
    return fd


class Link(object):
    """Packets between two fds, each delayed ``delay`` s and dropped with probability ``loss``."""

    def __init__(self, fd_a, fd_b, delay, loss, rng):
        self.peer = {fd_a: fd_b, fd_b: fd_a}
        self.delay, self.loss, self.rng = delay, loss, rng
        self.queue = []          # (due, seq, out fd, packet)
        self.seq = 0
        self.counts = {'forwarded': 0, 'dropped': 0}
        self.running = True

    def receive(self, fd, now):
        packet = os.read(fd, MTU)
        if self.rng.random() < self.loss:
            self.counts['dropped'] += 1
            return
        self.seq += 1
        heapq.heappush(self.queue, (now + self.delay, self.seq, self.peer[fd], packet))

    def deliver(self, now):
        while self.queue and self.queue[0][0] <= now:
            _, _, fd, packet = heapq.heappop(self.queue)
            try:
                os.write(fd, packet)
                self.counts['forwarded'] += 1
            except OSError:   # device down (namespace going away): drop
                self.counts['dropped'] += 1

    def run(self):
        fds = list(self.peer)
        while self.running:
            now = time.monotonic()
            self.deliver(now)
            timeout = max(0.0, self.queue[0][0] - now) if self.queue else 0.5
            try:
                ready, _, _ = select.select(fds, [], [], timeout)
            except InterruptedError:
                continue
            now = time.monotonic()
            for fd in ready:
                self.receive(fd, now)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('ns_a')
    ap.add_argument('if_a')
    ap.add_argument('ns_b')
    ap.add_argument('if_b')
    ap.add_argument('--delay-ms', type=float, default=0.0)
    ap.add_argument('--loss-pct', type=float, default=0.0)
    ap.add_argument('--seed', type=int, default=0)
    ap.add_argument('--ready-file', default='')
    args = ap.parse_args(argv)
    if not 0.0 <= args.loss_pct <= 100.0 or args.delay_ms < 0.0:
        ap.error('need 0 <= loss-pct <= 100 and delay-ms >= 0')
    fd_a = open_tun_in(args.ns_a, args.if_a)
    fd_b = open_tun_in(args.ns_b, args.if_b)
    link = Link(fd_a, fd_b, args.delay_ms / 1e3, args.loss_pct / 100.0, random.Random(args.seed))

    def stop(*_):
        link.running = False
    signal.signal(signal.SIGINT, stop)
    signal.signal(signal.SIGTERM, stop)
    if args.ready_file:
        open(args.ready_file, 'w').close()
    link.run()
    print('two_hosts_link: %(forwarded)d packets forwarded, %(dropped)d dropped' % link.counts, flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())

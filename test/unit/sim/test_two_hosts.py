"""tools/two_hosts.sh and its user-space link tools/two_hosts_link.py, without network namespaces: the link's
delay and loss on a pair of sockets, the script's clean skip when it cannot make namespaces. The two-host
run itself: test/ros/test_two_hosts.py (rostest two_hosts.test)."""
import os
import random
import shutil
import socket
import subprocess
import time

import pytest
from conftest import ROOT, load_script

two_hosts_link = load_script('tools', 'two_hosts_link.py')


def pair():
    a, b = socket.socketpair(socket.AF_UNIX, socket.SOCK_DGRAM)
    a.setblocking(False)
    b.setblocking(False)
    return a, b


def drain(sock):
    out = []
    while True:
        try:
            out.append(sock.recv(65536))
        except BlockingIOError:
            return out


def test_link_delays_every_packet_and_forwards_both_ways():
    a_outer, a_inner = pair()      # a_outer: the "namespace A" side; a_inner: the link's end
    b_outer, b_inner = pair()
    link = two_hosts_link.Link(a_inner.fileno(), b_inner.fileno(), 0.05, 0.0, random.Random(0))
    a_outer.send(b'ping')
    b_outer.send(b'pong')
    t0 = time.monotonic()
    for fd in (a_inner.fileno(), b_inner.fileno()):
        link.receive(fd, t0)
    link.deliver(t0 + 0.049)
    assert drain(b_outer) == [] and drain(a_outer) == []          # not before the delay
    link.deliver(t0 + 0.05)
    assert drain(b_outer) == [b'ping'] and drain(a_outer) == [b'pong']
    assert link.counts == {'forwarded': 2, 'dropped': 0}


def test_link_drops_its_share():
    a_outer, a_inner = pair()
    b_outer, b_inner = pair()
    link = two_hosts_link.Link(a_inner.fileno(), b_inner.fileno(), 0.0, 0.1, random.Random(1))
    for i in range(2000):
        a_outer.send(b'%d' % i)
        link.receive(a_inner.fileno(), 0.0)
        link.deliver(0.0)
        drain(b_outer)
    assert 150 < link.counts['dropped'] < 250                    # 10 % of 2000, binomial sd 13
    assert link.counts['forwarded'] + link.counts['dropped'] == 2000


@pytest.mark.skipif(shutil.which('setpriv') is None or os.geteuid() != 0, reason='needs root and setpriv')
def test_script_skips_cleanly_without_root():
    proc = subprocess.run(['setpriv', '--reuid=65534', '--regid=65534', '--clear-groups',
                           os.path.join(ROOT, 'tools', 'two_hosts.sh')],
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True, timeout=30)
    assert proc.returncode == 77, proc.stdout
    assert proc.stdout.startswith('SKIP: ') and 'root' in proc.stdout


def test_script_refuses_unknown_arguments():
    proc = subprocess.run([os.path.join(ROOT, 'tools', 'two_hosts.sh'), '--bogus'], stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, universal_newlines=True, timeout=30)
    assert proc.returncode == 2 and 'unknown argument --bogus' in proc.stdout

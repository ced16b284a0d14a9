"""Sphinx-like ground-truth telemetry over TCP, and the ``tlm-data-logger`` stand-in client (no rospy).

Stage: telemetry (simulator side). ``TelemetryServer`` serves each sample as
a block of ``KEY : VALUE`` lines (``anafi_sim.telemetry.protocol.format_sample``)
ended by a blank line to every connected client; ``publish`` never blocks
the simulator: sockets are non-blocking, a client whose unsent backlog
exceeds ``max_backlog`` bytes (a slow reader) is closed and counted.

``run_logger`` is the logic of ``scripts/tlm_data_logger.py``, the stand-in
for Sphinx's ``tlm-data-logger [-r RATE] inet:HOST:PORT``: it prints every
complete block it receives unchanged. ``-r RATE`` is read as the minimum
period in *milliseconds* between printed samples, measured on the samples'
``timestamp`` values (simulation time), so decimation is the same at any
real-time factor; 0 prints every sample. A sample whose timestamp goes back
(simulator restart) is always printed and restarts the decimation.
Exit codes: 0 when the server closes the connection, 1 when it cannot
connect (message on stderr) or stdout is closed, 2 for bad arguments.
"""
import argparse
import errno
import re
import select
import socket
import threading

from anafi_sim.telemetry.protocol import DEFAULT_PREFIX, STREAM_ID_MAX, format_sample

BLOCK_END = b'\n\n'


class _Client(object):
    __slots__ = ('sock', 'address', 'backlog')

    def __init__(self, sock, address):
        self.sock = sock
        self.address = address
        self.backlog = b''


class TelemetryServer(object):
    """TCP server pushing telemetry blocks to every client (host, port; port 0 = ephemeral).

    ``stream_id`` (an int in [1, STREAM_ID_MAX], or None): printed first in every block
    (``protocol.format_sample``) so that a reader can tell this simulator's stream from another's.
    """

    def __init__(self, host='127.0.0.1', port=9060, prefix=DEFAULT_PREFIX, max_backlog=65536, stream_id=None):
        if stream_id is not None and not (isinstance(stream_id, int) and 0 < stream_id <= STREAM_ID_MAX):
            raise ValueError('stream_id must be an integer in [1, %d] or None, got %r' % (STREAM_ID_MAX, stream_id))
        self.stream_id = stream_id
        self.host = host
        self.requested_port = int(port)
        self.prefix = prefix
        self.max_backlog = int(max_backlog)
        self.port = None                 # bound port, set by start()
        self.clients_accepted = 0
        self.clients_dropped_slow = 0    # closed because they did not keep up
        self.clients_disconnected = 0    # closed by the peer / send error
        self.samples_published = 0
        self._clients = []
        self._lock = threading.Lock()
        self._listener = None
        self._thread = None
        self._stop = threading.Event()

    @property
    def client_count(self):
        """Number of connected clients."""
        return len(self._clients)

    def start(self):
        """Bind, listen and start accepting clients (OSError if the port is taken)."""
        listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            listener.bind((self.host, self.requested_port))
            listener.listen(8)
        except OSError:
            listener.close()
            raise
        self._listener = listener
        self.port = listener.getsockname()[1]
        self._stop.clear()
        self._thread = threading.Thread(target=self._accept_loop, name='telemetry_accept')
        self._thread.daemon = True
        self._thread.start()
        return self.port

    def _accept_loop(self):
        listener = self._listener
        while not self._stop.is_set():
            try:
                readable, _, _ = select.select([listener], [], [], 0.2)
            except (OSError, ValueError):
                return
            if not readable:
                continue
            try:
                sock, address = listener.accept()
            except OSError:
                continue
            sock.setblocking(False)
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            with self._lock:
                self._clients.append(_Client(sock, address))
                self.clients_accepted += 1

    def publish(self, sample):
        """Send one ``TelemetrySample`` to every client without blocking; returns the number of clients served."""
        if not self._clients:
            return 0
        data = (format_sample(sample, self.prefix, self.stream_id) + '\n').encode('ascii')
        self.samples_published += 1
        return self.publish_raw(data)

    def publish_raw(self, data):
        """Send already formatted bytes to every client (non-blocking; slow/dead clients are closed)."""
        served = 0
        with self._lock:
            dead = None
            for client in self._clients:
                payload = client.backlog + data if client.backlog else data
                try:
                    sent = client.sock.send(payload)
                except (BlockingIOError, InterruptedError):
                    sent = 0
                except OSError:
                    dead = (dead or []) + [(client, False)]
                    continue
                client.backlog = payload[sent:]
                if len(client.backlog) > self.max_backlog:
                    dead = (dead or []) + [(client, True)]
                    continue
                served += 1
            if dead:
                for client, slow in dead:
                    self._clients.remove(client)
                    if slow:
                        self.clients_dropped_slow += 1
                    else:
                        self.clients_disconnected += 1
                    _close(client.sock)
        return served

    def stop(self):
        """Stop accepting, close every client (their readers see end of stream) and the listener."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(2.0)
            self._thread = None
        if self._listener is not None:
            _close(self._listener)
            self._listener = None
        with self._lock:
            for client in self._clients:
                _close(client.sock)
            self._clients = []


def _close(sock):
    try:
        sock.shutdown(socket.SHUT_RDWR)
    except OSError:
        pass
    sock.close()


# --------------------------------------------------------------------- client
def parse_endpoint(text):
    """'inet:HOST:PORT' -> (host, port); ValueError otherwise."""
    parts = text.split(':')
    if len(parts) != 3 or parts[0] != 'inet' or not parts[1]:
        raise ValueError('endpoint must look like inet:HOST:PORT, got %r' % (text,))
    try:
        port = int(parts[2])
    except ValueError:
        raise ValueError('bad port in %r' % (text,))
    if not 0 < port < 65536:
        raise ValueError('port out of range in %r' % (text,))
    return parts[1], port


def parse_logger_args(argv):
    """Command line of tlm_data_logger.py -> (rate_ms, host, port); ValueError with usage on error."""
    parser = argparse.ArgumentParser(
        prog='tlm_data_logger.py', add_help=True,
        description='Print the simulated Anafi ground-truth telemetry (stand-in for Sphinx tlm-data-logger).')
    parser.add_argument('-r', '--rate', type=float, default=0.0,
                        help='minimum period in ms between printed samples, on sample timestamps (0 = all)')
    parser.add_argument('endpoint', help='inet:HOST:PORT')

    class _Error(Exception):
        pass

    def _error(message):
        raise _Error(message)
    parser.error = _error
    try:
        args = parser.parse_args(argv)
    except _Error as error:
        raise ValueError('%s\n%s' % (error, parser.format_usage().strip()))
    if not (args.rate >= 0.0 and args.rate < float('inf')):
        raise ValueError('-r RATE must be a finite number >= 0 (ms), got %r' % (args.rate,))
    host, port = parse_endpoint(args.endpoint)
    return args.rate, host, port


def block_timestamp(block):
    """Value of the ``...timestamp : V`` line of a block (bytes), or None."""
    i = block.find(b'timestamp')
    if i < 0:
        return None
    j = block.find(b':', i)
    k = block.find(b'\n', j)
    try:
        return float(block[j + 1:k if k >= 0 else len(block)])
    except ValueError:
        return None


class BlockDecimator(object):
    """Keeps blocks at least ``period`` [s] apart on their timestamps (0 = keep all)."""

    def __init__(self, period):
        self.period = period
        self._last = None

    def keep(self, block):
        if self.period <= 0.0:
            return True
        stamp = block_timestamp(block)
        if stamp is None:
            return True
        last = self._last
        if last is None or stamp < last or stamp - last >= self.period - 1e-9:
            self._last = stamp
            return True
        return False


def run_logger(argv, out, err, connect_timeout=5.0):
    """Body of tlm_data_logger.py; ``out``/``err`` are binary/text streams. Returns the exit code."""
    try:
        rate_ms, host, port = parse_logger_args(argv)
    except ValueError as error:
        err.write('tlm_data_logger: %s\n' % (error,))
        err.flush()
        return 2
    except SystemExit as done:           # --help
        return int(done.code or 0)
    try:
        sock = socket.create_connection((host, port), timeout=connect_timeout)
    except OSError as error:
        err.write('tlm_data_logger: cannot connect to inet:%s:%d: %s\n' % (host, port, error))
        err.flush()
        return 1
    sock.settimeout(None)
    decimator = BlockDecimator(rate_ms / 1000.0)
    pending = b''
    try:
        while True:
            try:
                chunk = sock.recv(65536)
            except InterruptedError:
                continue
            except OSError:
                return 0                  # connection reset: the simulator went away
            if not chunk:
                return 0
            pending += chunk
            end = pending.rfind(BLOCK_END)
            if end < 0:
                continue
            complete, pending = pending[:end + 2], pending[end + 2:]
            if decimator.period > 0.0:
                kept = [b + BLOCK_END for b in complete[:-2].split(BLOCK_END) if decimator.keep(b)]
                if not kept:
                    continue
                complete = b''.join(kept)
            out.write(complete)
            out.flush()
    except (BrokenPipeError, IOError) as error:
        if getattr(error, 'errno', None) not in (None, errno.EPIPE):
            err.write('tlm_data_logger: %s\n' % (error,))
        return 1
    except KeyboardInterrupt:
        return 130
    finally:
        sock.close()


def checked_bind_host(host, allow_remote=False):
    """The address the telemetry server may bind: a loopback address (127.0.0.0/8, ::1, ``localhost``) unless
    ``allow_remote`` (``~allow_remote_telemetry``: the two-host layout); ValueError otherwise. The telemetry is
    plain text without authentication, so it stays on the host unless asked for."""
    import ipaddress
    text = str(host).strip()
    if text == 'localhost':
        return text
    try:
        address = ipaddress.ip_address(text)
    except ValueError:
        if allow_remote and re.match(r'^[A-Za-z0-9](?:[A-Za-z0-9.-]{0,252})$', text):
            return text
        raise ValueError('telemetry_host must be an IP address or localhost, got %r' % text[:100])
    if address.is_loopback or allow_remote:
        return text
    raise ValueError('telemetry_host %s is not a loopback address: the telemetry would be readable from the '
                     'network (set ~allow_remote_telemetry true to allow it)' % text)

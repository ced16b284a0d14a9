"""Which telemetry stream the interface reads: our simulator's port and stream id (pure, no ROS).

Stage: telemetry -> **interface**. The simulated Anafi serves its telemetry on the port it was told, or on
any free one (port 0), and marks every sample with a stream id that is new at every start
(``anafi_sim.telemetry.protocol.STREAM_ID_KEY``); it sets both as parameters
(``~telemetry_bound_port``, ``~telemetry_stream_id``). ``SimulatorSource`` reads them, through the
node's parameter getter, before each start of the telemetry command: the command's ``inet:HOST:PORT``
argument gets the bound port, and the interface core refuses samples of any other stream id. Against
the real Sphinx there is no simulator node: the command runs as given and any stream is read.
"""

#: start of the message of ``SimulatorSource.read`` while the simulator has not set its parameters yet
WAITING_FOR_SIMULATOR = 'waiting for the simulator'
BOUND_PORT_PARAM = 'telemetry_bound_port'
STREAM_ID_PARAM = 'telemetry_stream_id'


def with_port(argv, port):
    """``argv`` with the port of its ``inet:HOST:PORT`` argument replaced by ``port``; ValueError without one."""
    out = list(argv)
    for i, arg in enumerate(out):
        parts = arg.split(':')
        if len(parts) == 3 and parts[0] == 'inet' and parts[1]:
            out[i] = 'inet:%s:%d' % (parts[1], port)
            return out
    raise ValueError('the telemetry command has no inet:HOST:PORT argument to put the simulator\'s port in: %r'
                     % (argv,))


class SimulatorSource(object):
    """The port and stream id of the simulator node ``node`` (a ROS name relative to the interface's
    namespace, e.g. ``anafi_sim``), read with ``get_param(name)`` (returns None when the parameter is
    not set). ``prepare(argv)`` is the supervisor's hook: it raises ValueError while the simulator has
    not bound its port yet (the supervisor retries with back-off)."""

    def __init__(self, node, get_param):
        self.node = node.rstrip('/')
        self._get = get_param
        self.port = None
        self.stream_id = None

    def _read(self, name):
        return self._get('%s/%s' % (self.node, name))

    def read(self):
        """(port, stream id) the simulator set now; ValueError when missing or invalid."""
        port = self._read(BOUND_PORT_PARAM)      # before the id: the simulator sets the id first
        stream_id = self._read(STREAM_ID_PARAM)
        if port is None or stream_id is None:
            raise ValueError('%s %s to serve its telemetry (parameters %s/%s and %s/%s not set yet)' % (
                WAITING_FOR_SIMULATOR, self.node, self.node, BOUND_PORT_PARAM, self.node, STREAM_ID_PARAM))
        for name, value, high in ((BOUND_PORT_PARAM, port, 65535), (STREAM_ID_PARAM, stream_id, 2 ** 31 - 1)):
            if isinstance(value, bool) or not isinstance(value, int) or not 0 < value <= high:
                raise ValueError('%s/%s must be an integer in [1, %d], got %r' % (self.node, name, high, value))
        return port, stream_id

    def prepare(self, argv):
        """The command with the simulator's current port; remembers the port and stream id."""
        port, stream_id = self.read()
        out = with_port(argv, port)
        self.port, self.stream_id = port, stream_id
        return out

"""The controllers by name: the one list the node, the engine, the launch check, fleets and the reports read.

Pure (no rospy, no anafi_sim): an ``Entry`` names, for one controller,

- ``name``: what ``controller:=``, a fleet's ``controller:``, the engine's ``controller`` and the reports use;
- ``core``: its ``anafi_control.contract.Controller`` subclass as ``'package.module:Class'`` (imported when
  asked for, ``core_class``), built from its parameters by ``Class.from_config`` (the one reader of its YAML,
  for the node and the engine alike);
- ``config``: its YAML under anafi_sim/config/ (the node's ~params; the engine reads the same file);
- ``node``: the node adapter that runs it in controller_node.py (``'contract'``: the generic one, enough for
  any controller of the contract), or None when it does not run as one node;
- ``engine``: the in-process engine's adapter (``'contract'``: the generic one);
- ``launch``: the launch file that starts it for one drone, with ``launch_args`` (``controller.launch``
  with ``controller:=NAME``: the generic one); ``experiment``: ``controller:=NAME`` of experiment.launch
  takes it (False: a variant reached otherwise, e.g. pid_single through ``pid_mode:=single``);
- ``batch``: ``'paper'`` (the paper's controllers: every batch runs them), ``'beyond'`` (a column of the
  in-process batch beyond the paper) or None; ``label``: its name in reports.

Adding a controller: its core (a Controller subclass), its YAML and one ``Entry`` in ``ENTRIES``
(docs/architecture.md, "Adding a controller"). ``register`` adds one at run time (tests, plug-ins).
"""
import collections
import importlib

GENERIC = 'contract'
"""The adapter (node and engine) of any controller of the contract: built by its class's ``from_config``."""
GENERIC_LAUNCH = 'controller.launch'
"""The launch file of a controller run by the generic node (``controller:=NAME``, its YAML NAME.yaml)."""
BATCH_GROUPS = ('paper', 'beyond')


class Entry(collections.namedtuple('Entry', 'name core config node engine launch launch_args experiment batch '
                                            'label')):
    """One controller (see the module doc)."""

    def core_class(self):
        """The Controller subclass ``core`` names (imported now)."""
        module, _, cls = self.core.partition(':')
        return getattr(importlib.import_module(module), cls)


def entry(name, core, config=None, node=GENERIC, engine=GENERIC, launch=GENERIC_LAUNCH, launch_args=None,
          experiment=True, batch=None, label=None):
    """An Entry with the generic defaults: node and engine adapters ``contract``, ``controller.launch`` with
    ``controller:=NAME`` and the YAML ``NAME.yaml``, label NAME."""
    config = config or name + '.yaml'
    if launch_args is None:
        launch_args = ()
        if launch == GENERIC_LAUNCH:
            launch_args = (('controller', name),) + ((('config', config),) if config != name + '.yaml' else ())
    if batch not in (None,) + BATCH_GROUPS:
        raise ValueError('batch must be one of %s or None, got %r' % (', '.join(BATCH_GROUPS), batch))
    return Entry(name, core, config, node, engine, launch, tuple(launch_args), experiment, batch,
                 label or name)


#: every controller, in the order reports list them
ENTRIES = collections.OrderedDict((e.name, e) for e in (
    entry('mpc', 'anafi_control.mpc_tracking:MpcTracking', node='mpc_paths', launch='mpc.launch',
          batch='paper', label='MPC'),
    entry('pid', 'anafi_control.pid_framework:PidTracking', 'pid.yaml', node='pid_framework', engine='pid_graph',
          launch='pid.launch', launch_args=(('mode', 'distributed'),), batch='paper', label='PID'),
    entry('pid_single', 'anafi_control.pid_framework:PidTracking', 'pid.yaml', node='pid_framework',
          engine='pid_loops',
          launch='pid.launch', launch_args=(('mode', 'single'),), experiment=False, label='PID (one node)'),
    entry('preview_mpc', 'anafi_control.preview_mpc:PreviewMpc', node='preview_paths', engine='preview_model',
          launch='preview_mpc.launch', batch='beyond', label='preview MPC'),
))


def names():
    """Every registered name, in order."""
    return tuple(ENTRIES)


def get(name):
    """The Entry of ``name``; ValueError naming the known ones when there is none."""
    try:
        return ENTRIES[name]
    except (KeyError, TypeError):
        raise ValueError('unknown controller %r (known: %s)' % (name, ', '.join(ENTRIES)))


def node_names():
    """The names controller_node.py runs (~controller)."""
    return tuple(n for n, e in ENTRIES.items() if e.node is not None)


def experiment_names():
    """The values ``controller:=`` of experiment.launch takes."""
    return tuple(n for n, e in ENTRIES.items() if e.experiment)


def batch_names(group):
    """The names of a batch group ('paper' or 'beyond'), in order."""
    if group not in BATCH_GROUPS:
        raise ValueError('batch group must be one of %s, got %r' % (', '.join(BATCH_GROUPS), group))
    return tuple(n for n, e in ENTRIES.items() if e.batch == group)


def labels():
    """{name: label} of every controller."""
    return collections.OrderedDict((n, e.label) for n, e in ENTRIES.items())


class register(object):
    """Add ``entry_`` to the registry (ValueError when its name is taken); as a context manager, removed again
    on exit (tests)."""

    def __init__(self, entry_):
        if not isinstance(entry_, Entry):
            raise ValueError('register takes a registry.Entry, got %r' % (entry_,))
        if entry_.name in ENTRIES:
            raise ValueError('controller %r is already registered' % entry_.name)
        self.entry = entry_
        ENTRIES[entry_.name] = entry_

    def __enter__(self):
        return self.entry

    def __exit__(self, *exc):
        ENTRIES.pop(self.entry.name, None)
        return False

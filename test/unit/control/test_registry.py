"""anafi_control.registry: the one list of controller names, read by the node, the engine, the launch check,
fleets and the reports; a controller added with its core, its YAML and one entry."""
import ast
import glob
import os
import re
import xml.etree.ElementTree as ET

import pytest
from conftest import ROOT

from anafi_control import registry
from anafi_control.contract import Controller, CycleOutput, OK

REGISTRY = os.path.join(ROOT, 'anafi_control', 'registry.py')
SOURCES = sorted(p for folder in ('anafi_sim', 'anafi_control', 'anafi_lab')
                 for p in glob.glob(os.path.join(ROOT, folder, '**', '*.py'), recursive=True) if p != REGISTRY)
LAUNCH_FILES = sorted(glob.glob(os.path.join(ROOT, 'anafi_sim', 'launch', '*.launch')))


def _names_in(node):
    """The registry names among the string constants of a literal tuple / list / set / dict keys, or of a
    text such as 'mpc,pid' or 'mpc|pid'."""
    names = set(registry.names())
    if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
        items = node.elts
    elif isinstance(node, ast.Dict):
        items = [k for k in node.keys if k is not None]
    elif isinstance(node, ast.Constant) and isinstance(node.value, str):
        parts = [p.strip() for p in re.split(r'[,|]', node.value)]
        return set(parts) & names if all(p in names for p in parts) else set()
    else:
        return set()
    return set(i.value for i in items if isinstance(i, ast.Constant) and i.value in names)


#: data keyed by controller, not a list of them: the paper's published figures
DATA = ('PAPER_TABLE3',)


def test_no_module_lists_the_controllers_but_the_registry():
    found = []
    for path in SOURCES:
        tree = ast.parse(open(path).read(), filename=path)
        data = set(id(n.value) for n in ast.walk(tree) if isinstance(n, ast.Assign)
                   and any(isinstance(t, ast.Name) and t.id in DATA for t in n.targets))
        for node in ast.walk(tree):
            names = set() if id(node) in data else _names_in(node)
            if len(names) >= 2:
                found.append('%s:%d %s' % (os.path.relpath(path, ROOT), node.lineno, sorted(names)))
    assert not found, 'controller names listed outside anafi_control/registry.py:\n' + '\n'.join(found)


def test_no_launch_file_lists_the_controllers():
    found = []
    for path in LAUNCH_FILES:
        for expr in re.findall(r'\$\(eval ([^"]*)\)"', open(path).read()):
            names = set(re.findall(r"'(\w+)'", expr)) & set(registry.names())
            if len(names) >= 2:
                found.append('%s: %s' % (os.path.basename(path), expr))
    assert not found, 'controller names listed in launch files:\n' + '\n'.join(found)


def test_every_entry_names_a_controller_of_the_contract_with_its_yaml_and_launch_file():
    from anafi_sim import paths
    for entry in registry.ENTRIES.values():
        cls = entry.core_class()
        assert isinstance(cls, type) and issubclass(cls, Controller), entry
        assert os.path.isfile(paths.config_path(entry.config)), entry
        assert os.path.isfile(os.path.join(ROOT, 'anafi_sim', 'launch', entry.launch)), entry


def test_the_readers_know_every_key_of_the_shipped_yamls():
    """Each core's ``from_config`` reads its YAML: every key is its parameter or the node's wiring."""
    from anafi_control.contract import NODE_KEYS
    from anafi_sim import paths, run_files
    for entry in registry.ENTRIES.values():
        config = run_files.read_yaml(paths.config_path(entry.config), {})
        unknown = sorted(k for k in config if k not in entry.core_class().CONFIG_KEYS and k not in NODE_KEYS)
        assert not unknown, (entry.name, unknown)


def test_register_refuses_a_taken_name_and_is_undone_on_exit():
    with pytest.raises(ValueError):
        registry.register(registry.entry('mpc', 'anafi_control.mpc_tracking:MpcTracking'))
    with registry.register(registry.entry('toy_reg', 'x:Y')):
        assert 'toy_reg' in registry.names()
    assert 'toy_reg' not in registry.names()
    with pytest.raises(ValueError, match='unknown controller'):
        registry.get('no_such')


# ------------------------------------------------------------------------------------ a toy controller
class Toy(Controller):
    """Flies towards the waypoint with a pitch proportional to the distance (a toy, for the registry tests):
    one parameter of its own, ``gain``."""
    RATE = 10.0
    CONFIG_KEYS = Controller.CONFIG_KEYS + ('gain',)

    def __init__(self, gain=1.0, **kwargs):
        Controller.__init__(self, **kwargs)
        self.gain = float(gain)

    @classmethod
    def from_config(cls, config, limits=None):
        core = Controller.from_config.__func__(cls, config, limits)
        core.gain = float(config.get('gain', 1.0))
        return core

    def _compute(self, t, inputs):
        dx = inputs.waypoint[0] - inputs.pos[0]
        return CycleOutput((0.0, max(-5.0, min(5.0, self.gain * dx)), 0.0, 0.0), True, OK, OK, None)


TOY_YAML = '''# the toy's parameters (a controller's YAML: anafi_sim/config/NAME.yaml)
gain: 0.8
state_timeout: 0.5
waypoint_timeout: 1.0
geofence_radius: 120.0
state_topic: drone/odom
'''


@pytest.fixture
def toy(tmp_path):
    """The toy registered with its YAML (in a folder of the test: an absolute path stands for the file the
    package would ship as anafi_sim/config/toy.yaml)."""
    path = tmp_path / 'toy.yaml'
    path.write_text(TOY_YAML)
    with registry.register(registry.entry('toy', '%s:Toy' % __name__, config=str(path))) as entry:
        yield entry


def test_a_new_controller_is_accepted_by_the_launch_check_and_fleets(toy):
    from anafi_sim import launch_check
    from anafi_sim.mission import fleet
    assert launch_check.controller('toy') is None
    assert 'toy' in launch_check.controller('tyo')
    drone = fleet.drone_from_dict({'name': 'a', 'controller': 'toy', 'scenario': 'straight_1'})
    assert drone.controller == 'toy'
    with pytest.raises(ValueError, match='toy'):
        fleet.drone_from_dict({'name': 'a', 'controller': 'tyo', 'scenario': 'straight_1'})


def test_a_new_controller_gets_the_generic_launch_file_in_a_fleet(toy):
    from anafi_sim.mission import fleet
    drone = fleet.drone_from_dict({'name': 'a', 'controller': 'toy', 'scenario': 'straight_1'})
    lines = fleet.drone_launch_lines(drone, 7001, '/x/straight_1.yaml',
                                     {'output': 'log', 'mirror': 'false', 'mirror_rate': 100.0, 'evaluate': False})
    root = ET.fromstring('<launch>%s</launch>' % '\n'.join(lines))
    includes = [i for i in root.iter('include') if i.get('file').endswith('/controller.launch')]
    assert len(includes) == 1
    args = dict((a.get('name'), a.get('value')) for a in includes[0].iter('arg'))
    assert args['controller'] == 'toy' and args['drone_name'] == 'a'


def test_a_new_controller_flies_in_the_engine(toy):
    """The engine builds it from its YAML through its ``from_config`` (the node's reader too) and flies it."""
    from anafi_lab.engine import engine as E
    run = E.Engine('straight_1', 'toy', controller_params={'gain': 0.5})
    assert run.name == 'straight_1_toy'
    core = run._factory()
    assert isinstance(core, Toy) and core.gain == 0.5 and core.gate.envelope.geofence_radius == 120.0
    result = E.Engine('static_wp0', 'toy').run()
    assert result.summary['state'] in ('final', 'incomplete') and result.info is not None
    with pytest.raises(ValueError, match='unknown toy parameter'):
        E.Engine('straight_1', 'toy', controller_params={'gian': 0.5})


def test_a_new_controller_runs_in_the_node_with_the_generic_adapter():
    """controller_node.py takes ~controller toy: the generic adapter builds it from its ~params."""
    pytest.importorskip('rospy')
    from anafi_sim.nodes import controller_node
    from anafi_sim.ros.params import ParamReader
    params = {'gain': 2.0, 'state_timeout': 0.25, 'geofence_radius': 100.0, 'state_topic': 'x'}

    class Ctx(object):
        def get_param(self, name, default=None):
            return params.get(name, default)

        def has_param(self, name):
            return name in params

    class Node(object):
        ctx = Ctx()

    with registry.register(registry.entry('toy', '%s:Toy' % __name__)) as entry:
        assert 'toy' in registry.node_names()
        adapter = controller_node.ADAPTERS[entry.node](Node(), entry)
        core = adapter.build(ParamReader(lambda name, default: params.get(name, default)))
    assert isinstance(core, Toy) and core.gain == 2.0 and adapter.label == 'toy'
    assert core.gate.envelope.geofence_radius == 100.0


@pytest.mark.parametrize('name', ['mpc', 'pid_single', 'preview_mpc'])
def test_the_node_and_the_engine_build_a_shipped_controller_alike(name):
    """The node (its ~params loaded from the YAML, as the launch file does) and the engine (the file) build the
    same controller: one reader of a controller's YAML."""
    pytest.importorskip('rospy')
    from anafi_lab.engine import engine as E
    from anafi_sim import paths, run_files
    from anafi_sim.nodes import controller_node
    from anafi_sim.ros.params import ParamReader
    entry = registry.get(name)
    params = run_files.read_yaml(paths.config_path(entry.config), {})

    class Ctx(object):
        def get_param(self, key, default=None):
            return params.get(key, default)

        def has_param(self, key):
            return key in params

    class Node(object):
        ctx = Ctx()

    node_core = controller_node.ADAPTERS[entry.node](Node(), entry).build(
        ParamReader(lambda key, default: params.get(key, default)))
    from anafi_sim.sim.bridge import MAX_TILT_DEG, MAX_VERTICAL_SPEED, MAX_YAW_RATE_DEG
    # the bridge's limits as the node has them without ~max_tilt_deg & co. (the engine's default: sim.yaml's)
    bridge = dict(max_tilt_deg=MAX_TILT_DEG, max_vertical_speed=MAX_VERTICAL_SPEED, max_yaw_rate_deg=MAX_YAW_RATE_DEG)
    engine_core = E.controller_factory(name, mapping=bridge)()
    assert type(node_core) is type(engine_core) is entry.core_class()
    assert vars(node_core.gate.envelope) == vars(engine_core.gate.envelope)
    if name == 'mpc':
        assert node_core.config() == engine_core.config() and node_core.yaw_config == engine_core.yaw_config
    elif name == 'preview_mpc':
        assert node_core.params == engine_core.params and node_core.model == engine_core.model
    else:
        assert node_core.framework.config == engine_core.framework.config

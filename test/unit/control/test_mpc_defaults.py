"""One source of MPC defaults: anafi_sim/config/mpc.yaml. The code defaults (anafi_control.mpc.DEFAULT_PARAMS,
anafi_control.mpc_tracking.DEFAULTS) and the dynamic_reconfigure defaults (cfg/Mpc.cfg) must equal it."""
import os

import pytest
import yaml

from anafi_control.contract import LIMIT_DEFAULTS
from anafi_control.mpc import DEFAULT_PARAMS
from anafi_control.mpc_tracking import DEFAULTS, RECONFIGURABLE, MpcTracking, mpc_params_from_flat
from conftest import ROOT, cfg_defaults

#: node-only keys of mpc.yaml (topic and frame names, read by the controller node)
NODE_KEYS = ('state_topic', 'waypoint_topic', 'command_topic', 'frame_id')
#: flat names of the MPC core's parameters as the YAML and the reconfigure server have them
FLAT_VMAX = ('v_max_x', 'v_max_y', 'v_max_z')


def _yaml():
    with open(os.path.join(ROOT, 'anafi_sim', 'config', 'mpc.yaml')) as f:
        return yaml.safe_load(f)


def _flat_code_default(key):
    """The code default of a flat MPC parameter (v_max split per axis, a_max as its common value)."""
    if key in FLAT_VMAX:
        return DEFAULT_PARAMS['v_max'][FLAT_VMAX.index(key)]
    value = DEFAULT_PARAMS[key]
    if isinstance(value, (tuple, list)):
        assert len(set(value)) == 1, key
        return value[0]
    return value


def test_every_yaml_key_is_known_and_equals_the_code_default():
    data = _yaml()
    core = set(DEFAULT_PARAMS) - {'v_max'} | set(FLAT_VMAX)
    unknown = sorted(set(data) - core - set(DEFAULTS) - set(NODE_KEYS) - {'yaw'})
    assert not unknown, 'mpc.yaml keys nobody reads: %s' % unknown
    for key, value in data.items():
        if key in DEFAULTS:
            assert value == DEFAULTS[key] and type(value) is type(DEFAULTS[key]), key
        elif key in core:
            assert value == pytest.approx(_flat_code_default(key), rel=1e-12), key
            assert isinstance(value, bool) == isinstance(_flat_code_default(key), bool), key
    assert set(DEFAULTS) <= set(data), 'tracking defaults missing in mpc.yaml: %s' % sorted(set(DEFAULTS) - set(data))
    # the YAML's MPC part builds the default controller
    flat = dict((k, v) for k, v in data.items() if k in core)
    assert mpc_params_from_flat(flat) == mpc_params_from_flat(dict((k, _flat_code_default(k)) for k in flat))


def test_the_yaml_sets_every_reconfigurable_parameter():
    assert set(RECONFIGURABLE) <= set(_yaml())


def test_reconfigure_defaults_equal_the_yaml():
    data, cfg = _yaml(), cfg_defaults('Mpc.cfg')
    assert sorted(cfg) == sorted(RECONFIGURABLE)
    for key, value in cfg.items():
        assert value == pytest.approx(data[key], rel=1e-12), key


def test_tracking_defaults_are_the_constructor_defaults():
    tr = MpcTracking()
    assert tr.gate.state_timeout == DEFAULTS['state_timeout']
    assert tr.gate.waypoint_timeout == DEFAULTS['waypoint_timeout']
    assert tr.twist_in_child_frame == DEFAULTS['twist_in_child_frame']
    assert tr.cum_reset_distance == DEFAULTS['cum_reset_distance']
    assert all(tr.gate.envelope.as_dict()[k] == DEFAULTS[k] for k in LIMIT_DEFAULTS)
    assert MpcTracking.RATE == DEFAULTS['rate'] == pytest.approx(1.0 / DEFAULT_PARAMS['dt'])
    assert tr.config() == dict((k, _yaml()[k]) for k in RECONFIGURABLE)


def test_the_flight_envelope_is_the_same_in_every_controller_yaml_and_the_code():
    with open(os.path.join(ROOT, 'anafi_sim', 'config', 'pid.yaml')) as f:
        pid = yaml.safe_load(f)
    with open(os.path.join(ROOT, 'anafi_sim', 'config', 'preview_mpc.yaml')) as f:
        preview = yaml.safe_load(f)
    data = _yaml()
    for key, value in LIMIT_DEFAULTS.items():
        assert data[key] == pid[key] == preview[key] == value == DEFAULTS[key], key

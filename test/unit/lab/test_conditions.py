"""anafi_lab.calibration.conditions (the firmware's wind handling and the conditions from a log) on synthetic
logs with a known wind, and the conditions profiles (anafi_sim.sim.conditions_profile) where runs are made."""
import collections
import math
import os

import pytest

from anafi_lab.calibration import conditions as cond
from anafi_lab.reports import conditions_report
from anafi_lab.engine import replay as fidelity
from anafi_lab.engine.engine import Engine
from anafi_sim.sim.conditions_profile import PROFILE_KEYS, list_conditions, load_conditions, profile_path
from anafi_sim.sim.drone_model import load_model_params

WIND = (-3.0, -4.0)          # m/s, world ENU (5 m/s)


def synthetic_log(gain, gust=0.0, seed=1):
    """The stand-in hovering at static_wp0's waypoint in a known wind (paper's MPC), recorded like the real logs
    (20 Hz, half floats, estimate only matters)."""
    engine = Engine('static_wp0', 'mpc', wind={'wind_x': WIND[0], 'wind_y': WIND[1], 'gust_std_horizontal': gust},
                    seed=seed,
                    settings={'wind_compensation': gain, 'wind_compensation_time_constant': 0.5})
    assert engine.run().ok
    return fidelity.run_log(engine, name='synthetic_mpc')


@pytest.fixture(scope='module')
def model():
    return load_model_params()


@pytest.fixture(scope='module')
def logs():
    return {'full': synthetic_log(1.0), 'half': synthetic_log(0.5), 'gusty': synthetic_log(1.0, gust=0.8)}


def test_the_wind_vector_of_a_synthetic_log(model, logs):
    for name in ('full', 'half', 'gusty'):
        c = cond.estimate_conditions(logs[name], model)
        tolerance = 0.08 if name != 'gusty' else 0.2
        assert c.wind_speed == pytest.approx(math.hypot(*WIND), rel=tolerance), name
        direction = (c.wind[0] * WIND[0] + c.wind[1] * WIND[1]) / (c.wind_speed * math.hypot(*WIND))
        assert direction > math.cos(math.radians(8.0)), name


def test_the_firmware_gain_of_a_synthetic_log(model, logs):
    """The gain K the firmware cancels is found from the commands (recomputed) and the held tilt."""
    for name, gain in (('full', 1.0), ('half', 0.5), ('gusty', 1.0)):
        contribution = cond.firmware_contribution(logs[name], model)
        fit = cond.fit_wind_handling({name: contribution})
        assert fit.gain == pytest.approx(gain, abs=0.06), name
        assert fit.samples > 100


def test_gusts_raise_the_gust_level(model, logs):
    calm = cond.estimate_conditions(logs['full'], model)
    gusty = cond.estimate_conditions(logs['gusty'], model)
    assert gusty.gust_std > calm.gust_std
    assert 0.0 < calm.position_noise < 0.05 and 0.0 < calm.velocity_noise < 0.05


def test_wind_speed_for_force_inverts_the_drag(model):
    for speed in (0.5, 3.0, 8.0):
        force = (model['drag_linear'] + model['drag_quadratic'] * speed) * speed
        assert cond.wind_speed_for_force(force, model) == pytest.approx(speed)


def test_the_section_replaces_itself():
    begin, end = conditions_report.SECTION_BEGIN, conditions_report.SECTION_END
    text = 'head\n\n' + begin + '\nold\n' + end + '\n\n## next\n'
    new = conditions_report.replace_section(text, begin + '\nnew\n' + end + '\n')
    assert 'old' not in new and 'new' in new and new.startswith('head') and new.rstrip().endswith('## next')
    assert conditions_report.existing_section(new).startswith(conditions_report.SECTION_BEGIN)
    assert conditions_report.replace_section('only', 'S\n') == 'only\n\nS\n'


# ------------------------------------------------------------------------------------------------ profiles
def test_the_real_flights_profile_loads():
    assert 'real_flights' in list_conditions()
    settings = load_conditions('real_flights')
    assert set(settings) <= set(PROFILE_KEYS)
    assert math.hypot(settings['wind_x'], settings['wind_y']) > 1.0
    assert settings['wind_compensation'] > 0.5
    assert load_conditions(profile_path('real_flights')) == settings
    assert load_conditions(None) == {}


def test_bad_profiles_are_refused(tmp_path):
    with pytest.raises(ValueError):
        load_conditions('no_such_conditions')
    with pytest.raises(ValueError):
        load_conditions('/etc/passwd')              # not a .yaml profile
    bad = tmp_path / 'bad.yaml'
    bad.write_text('wind_x: 1.0\nrate: 200\n')      # a node setting, not a model setting
    with pytest.raises(ValueError):
        load_conditions(str(bad))
    bad.write_text('wind_compensation: -1\n')
    with pytest.raises(ValueError):
        load_conditions(str(bad))


def test_engine_runs_in_conditions(tmp_path):
    """A profile under the engine's settings; --wind style overrides win; no profile = sim.yaml."""
    path = tmp_path / 'steady.yaml'
    path.write_text('wind_x: 2.0\nwind_y: 0.0\nwind_compensation: 1.0\n')
    engine = Engine('static_wp0', 'mpc', conditions=str(path))
    assert engine.settings['wind_x'] == 2.0 and engine.settings['wind_compensation'] == 1.0
    engine = Engine('static_wp0', 'mpc', conditions=str(path), wind={'wind_x': -1.0})
    assert engine.settings['wind_x'] == -1.0 and engine.settings['wind_compensation'] == 1.0
    assert Engine('static_wp0', 'mpc').settings['wind_x'] == 0.0


def test_sweep_spec_conditions_reach_every_task_and_row():
    from anafi_lab.engine import sweep
    spec = sweep.load_spec('real_flights')
    tasks = sweep.expand(spec)
    assert len(tasks) == 9 * 3 * 10
    assert all(t['conditions'] == 'real_flights' for t in tasks)
    assert {t['controller'] for t in tasks} == {'pid', 'mpc', 'preview_mpc'}
    rows = sweep.rows(tasks[:2], [None, None])
    assert rows[0]['conditions'] == 'real_flights'
    assert rows[0]['wind_x'] == load_conditions('real_flights')['wind_x']
    with pytest.raises(ValueError):
        sweep.expand(dict(spec, conditions='no_such_conditions'))


def test_predicted_section_has_the_seed_spread():
    from anafi_lab.reports.conditions_report import cells, predicted_section
    table = [{'ok': True, 'conditions': 'real_flights', 'scenario': 'circle_r1_v1', 'controller': 'mpc',
              'e_max': 1.0 + i, 'e_mu': 0.5, 'e_sigma': 0.1} for i in range(3)]
    table.append({'ok': False, 'conditions': 'real_flights', 'scenario': 'circle_r1_v1', 'controller': 'mpc',
                  'e_max': None, 'e_mu': None, 'e_sigma': None})
    stats = cells(table)[('real_flights', 'circle_r1_v1', 'mpc')]
    assert stats['e_max'][:4] == (2.0, 1.0, 1.0, 3.0) and stats['e_max'][4] == 3
    text = '\n'.join(predicted_section(table))
    assert '| real_flights | circle_r1_v1 | mpc | 3 | 2.00 +- 1.00 [1.00, 3.00] |' in text


def test_the_run_plot_shows_the_wind(tmp_path):
    from anafi_sim.mission.plots import run_figure
    from anafi_sim.mission.reference_log import read_log
    from anafi_sim.sim.conditions_profile import wind_text
    settings = load_conditions('real_flights')
    text = wind_text(settings)
    assert text.startswith('wind ') and 'gusts' in text and 'wind handling' in text
    assert wind_text({'wind_x': 0.0}) == ''
    log = synthetic_log(1.0)
    fig = run_figure(log, wind=settings)
    assert text in fig._suptitle.get_text()
    arrows = [a for ax in fig.axes for a in ax.texts if a.get_text().startswith('wind ')]
    assert arrows
    calm = run_figure(log)
    assert calm._suptitle is None or 'wind' not in calm._suptitle.get_text()


def test_fleet_drones_get_the_conditions():
    from anafi_sim.mission.fleet import launch_xml, load_fleet
    fleet = load_fleet('circles', 0)
    ports = dict((d.name, 9000 + i) for i, d in enumerate(fleet.drones))
    xml = launch_xml(fleet, ports, {}, '/tmp', conditions='real_flights')
    assert xml.count('<arg name="conditions" value="real_flights"/>') == len(fleet.drones)
    assert 'conditions' not in launch_xml(fleet, ports, {}, '/tmp')
    with pytest.raises(ValueError):
        launch_xml(fleet, ports, {}, '/tmp', conditions='../../etc/x')


def test_the_replays_store_round_trips_and_renders():
    import yaml
    settings = [cond.profile_settings((1.0, 2.0), 1.0, 0.5, 0.98, 0.25)]
    figures = collections.OrderedDict((('e_mu', 0.8), ('e_max', 6.2), ('tilt_mean', 0.2), ('e_hold', 0.2)))
    grid = collections.OrderedDict([((0, 'log_mpc'), [figures, None])])
    back = cond.grid_from_store(yaml.safe_load(cond.store_text(settings, [0, 1], grid, 'cmd')))
    assert back == grid
    assert cond.seed_means(back[(0, 'log_mpc')])['e_mu'] == (0.8, 0.8, 0.8)

    class Log(object):
        name = 'log_mpc'
    refs = {'log_mpc': collections.OrderedDict((('e_mu', 1.0), ('e_max', 6.2), ('tilt_mean', 0.25),
                                                ('e_hold', 0.2)))}
    text = conditions_report.fidelity_section([Log()], back, 0, refs, [0, 1], 'cmd')
    assert text.startswith(conditions_report.FIDELITY_BEGIN) and conditions_report.FIDELITY_END in text
    assert '| log_mpc | 0.800 [0.800, 0.800] vs 1.000 (0.80) |' in text


def test_the_real_flight_sections_rerender_identical_from_their_figures(tmp_path):
    """calibrate_conditions.py --render-only rewrites the profile and the "Real flights" sections of
    docs/calibration.md and docs/fidelity.md from benchmarks/results/real_flights.yaml: the same bytes."""
    import shutil
    from anafi_lab.cli import calibrate_conditions
    from anafi_sim import paths
    root = paths.checkout()
    logs = paths.reference_logs_dir('real')
    files = {'profile': os.path.join(root, 'anafi_sim', 'config', 'conditions', 'real_flights.yaml'),
             'report': os.path.join(root, 'docs', 'calibration.md'),
             'fidelity': os.path.join(root, 'docs', 'fidelity.md')}
    copies = {}
    for key, path in files.items():
        copies[key] = str(tmp_path / os.path.basename(path))
        shutil.copy(path, copies[key])
    calibrate_conditions.main(['--render-only', '--profile', copies['profile'], '--report', copies['report'],
                               '--fidelity', copies['fidelity'], '--workers', '1'])
    for key, path in files.items():
        with open(path) as a, open(copies[key]) as b:
            assert a.read() == b.read(), '%s differs from its re-render (calibrate_conditions.py --render-only)' % path

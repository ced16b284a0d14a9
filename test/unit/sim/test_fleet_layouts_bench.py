"""benchmarks/fleet_layouts.py: the verdict per drone (layout difference against the run-to-run spread), failed
runs left out of it, and the committed results file being what the script renders from its JSON."""
import importlib.util
import json
import os

import pytest

from conftest import ROOT


def _bench():
    spec = importlib.util.spec_from_file_location('fleet_layouts', os.path.join(ROOT, 'benchmarks', 'fleet_layouts.py'))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _run(layout, e_mu, error=None):
    run = {'layout': layout, 'drones': {'a1': {'truth': {'e_max': 1.0, 'e_mu': e_mu, 'e_sigma': 0.1},
                                                'estimate': {'e_max': 1.0, 'e_mu': e_mu, 'e_sigma': 0.1}}}}
    if error:
        run = {'layout': layout, 'error': error, 'drones': {}}
    return run


def _data(runs):
    return {'format': 1, 'fleet': 'f', 'repeats': 2, 'layouts': ['per_drone', 'shared'], 'timeout': 100.0,
            'drones': ['a1'], 'runs': runs,
            'machine': {'date': 'd', 'python': '3', 'cores': 2, 'cpu_model': 'c', 'load_start': [0.0, 0.0, 0.0]}}


@pytest.mark.parametrize('e_mu, verdict', [
    ((0.40, 0.42, 0.42, 0.43), 'within spread'),     # means 0.41 / 0.425, spreads 0.02 / 0.01: 0.015 <= 0.02
    ((0.40, 0.50, 0.41, 0.51), 'outside spread'),    # means 0.405 / 0.505, spreads 0.01: 0.1 > 0.01
    ((0.40, 0.50, 0.60, 0.51), 'within spread'),     # per_drone spread 0.2 covers the difference 0.095
])
def test_the_verdict_compares_the_layout_difference_with_the_larger_spread(e_mu, verdict):
    bench = _bench()
    runs = [_run(layout, v) for layout, v in zip(('per_drone', 'shared') * 2, e_mu)]
    c = bench.comparison(_data(runs))['a1/truth']
    assert c['verdict'] == verdict
    assert c['layouts']['per_drone']['e_mu'] == [e_mu[0], e_mu[2]]
    assert c['difference'] == pytest.approx((e_mu[1] + e_mu[3] - e_mu[0] - e_mu[2]) / 2.0)


def test_failed_runs_are_listed_but_not_compared():
    bench = _bench()
    runs = [_run('per_drone', 0.4), _run('shared', 0.4, error='time-out'), _run('per_drone', 0.41),
            _run('shared', 0.41)]
    data = _data(runs)
    c = bench.comparison(data)['a1/truth']
    assert c['verdict'].startswith('not measured') and c['layouts']['shared']['e_mu'] == [0.41]
    assert 'FAILED: time-out' in bench.markdown(data)


RESULTS_JSON = os.path.join(ROOT, 'benchmarks', 'results', 'fleet_layouts.json')


@pytest.mark.skipif(not os.path.exists(RESULTS_JSON), reason='no committed fleet_layouts results')
def test_the_committed_results_file_is_rendered_from_its_json():
    bench = _bench()
    with open(RESULTS_JSON) as f:
        data = json.load(f)
    with open(os.path.join(ROOT, 'benchmarks', 'results', 'fleet_layouts.md')) as f:
        assert f.read() == bench.markdown(data), 'rerun: python benchmarks/fleet_layouts.py --from-json'
    assert set(r['layout'] for r in data['runs'] if not r.get('error')) == {'per_drone', 'shared'}

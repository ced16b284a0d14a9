"""Live tuning leaves a trace (anafi_control.tuning): what one dynamic_reconfigure request changed, with the
value asked for, and whether the server clamped it to its range or the controller did not apply it. Before,
a `dynparam set` was not in the run's files and an out-of-range value was clamped without a word. The node
side (anafi_sim/ros/reconfigure.py: INFO / WARN on /rosout, /<drone>/tuning/changes, RUN.run.yaml `tuning`):
test/ros/test_experiment.py."""
from anafi_control.tuning import OUTCOMES, changes, describe

NAMES = ['r', 'q_cum', 'a_max', 'N']
MIN = {'r': 1e-6, 'q_cum': 0.0, 'a_max': 0.1, 'N': 5}
MAX = {'r': 10000.0, 'q_cum': 1000.0, 'a_max': 100.0, 'N': 200}
BEFORE = {'r': 0.2, 'q_cum': 1e-3, 'a_max': 5.0, 'N': 30, 'groups': {}}


def test_an_applied_change_is_recorded_with_old_and_new():
    applied = dict(BEFORE, a_max=5.5)
    out = changes(BEFORE, {'a_max': 5.5}, applied, NAMES, MIN, MAX)
    assert out == [{'parameter': 'a_max', 'old': 5.0, 'new': 5.5, 'requested': 5.5, 'outcome': 'applied'}]
    assert describe(out[0]) == 'a_max: 5.0 -> 5.5'


def test_a_clamped_value_is_reported_with_the_value_asked_for():
    """dynamic_reconfigure's server clamps to [min, max] before the node sees it: q_cum 5000 -> 1000."""
    applied = dict(BEFORE, q_cum=1000.0)
    out = changes(BEFORE, {'q_cum': 5000.0}, applied, NAMES, MIN, MAX)
    assert out[0]['outcome'] == 'clamped' and out[0]['requested'] == 5000.0 and out[0]['new'] == 1000.0
    assert 'outside [0.0, 1000.0]' in describe(out[0], MIN, MAX) and 'clamped to 1000.0' in describe(out[0], MIN, MAX)


def test_a_clamp_that_changes_nothing_is_still_reported():
    """Already at the bound (q_cum_vel 0, asked -1): no change, but the request was not honoured."""
    before = dict(BEFORE, q_cum=0.0)
    out = changes(before, {'q_cum': -1.0}, dict(before), NAMES, MIN, MAX)
    assert [(r['parameter'], r['outcome'], r['old'], r['new']) for r in out] == [('q_cum', 'clamped', 0.0, 0.0)]


def test_a_value_the_controller_refused_is_reported():
    out = changes(BEFORE, {'r': 3.0}, dict(BEFORE), NAMES, MIN, MAX)       # the node kept its value
    assert out[0]['outcome'] == 'refused' and out[0]['new'] == 0.2
    assert describe(out[0]).startswith('r: requested 3.0 not applied')


def test_unchanged_and_unasked_parameters_are_not_recorded():
    assert changes(BEFORE, {'r': 0.2, 'N': 30}, dict(BEFORE), NAMES, MIN, MAX) == []
    assert changes(BEFORE, {}, dict(BEFORE), NAMES, MIN, MAX) == []
    # the controller adjusting another parameter in the same request is recorded too
    out = changes(BEFORE, {'N': 40}, dict(BEFORE, N=40, a_max=4.0), NAMES, MIN, MAX)
    assert [(r['parameter'], r['outcome']) for r in out] == [('a_max', 'refused'), ('N', 'applied')]


def test_integers_and_floats_compare_by_value_and_outcomes_are_known():
    out = changes(BEFORE, {'N': 30.0}, dict(BEFORE), NAMES, MIN, MAX)
    assert out == []
    out = changes(BEFORE, {'N': 500}, dict(BEFORE, N=200), NAMES, MIN, MAX)
    assert out[0]['outcome'] == 'clamped'
    assert set(r['outcome'] for r in out) <= set(OUTCOMES)

"""Every report re-renders byte-identical from its template and its stored measured figures.

The committed reports are generated files: each is its template (anafi_lab/reports/templates/) filled with the
figures its run stored beside it. These checks read the stored figures (and nothing else of them): a report
edited by hand, or a template changed without re-rendering, fails here.
"""
import os

import pytest

from anafi_lab.reports import paper_tables
from anafi_sim import paths

RESULTS = os.path.join(paths.checkout(), 'benchmarks', 'results')
BATCHES = (('experiments.yaml', 'experiments.md'), (os.path.join('inprocess', 'experiments.yaml'),
                                                    os.path.join('inprocess', 'report.md')))


@pytest.mark.parametrize('records, report', BATCHES, ids=[r for _, r in BATCHES])
def test_batch_report_rerenders_identical(records, report):
    with open(os.path.join(RESULTS, report)) as stream:
        committed = stream.read()
    assert paper_tables.rerender(os.path.join(RESULTS, records)) == committed


def test_the_batch_report_quotes_the_figures_where_they_are_defined():
    """The static steps' geometry from their scenario files, the distributed PID graph's nodes from pid.launch."""
    from anafi_lab.reports import batch_facts
    steps = batch_facts.static_steps()
    assert steps == {'start': ['0', '0', '1'], 'waypoint': ['3', '2', '5'], 'yaws': ['0', '180']}
    assert batch_facts.pid_graph_nodes() == 8 and batch_facts.pid_graph_nodes('single') == 1

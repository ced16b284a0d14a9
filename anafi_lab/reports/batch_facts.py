"""Figures the batch report's words quote that are no run's result: the static steps' geometry (their scenario
files), the distributed PID framework's node count (pid.launch), the pacing's re-anchor lag and the paper's
computational-workload ratio. Read from where they are defined, so that the template holds only words."""
import xml.etree.ElementTree as ET

import yaml

from anafi_lab.paper import PAPER_CPU_RATIO, STATIC
from anafi_sim import paths
from anafi_sim.mission.trajectory import scenario_path
from anafi_sim.sim.clock import MAX_LAG


def _number(value):
    """A coordinate as the report writes it: '%g' (3.0 -> '3')."""
    return '%g' % value


def static_steps(names=STATIC):
    """{start, waypoint, yaws}: the static steps' hover point and waypoint [m] (shared by the steps) and each
    step's waypoint yaw [deg], as text, from their scenario files."""
    steps = []
    for name in names:
        with open(scenario_path(name)) as stream:
            steps.append(yaml.safe_load(stream))
    start, trajectory = steps[0]['start'], steps[0]['trajectory']
    return {'start': [_number(start[k]) for k in ('x', 'y', 'z')],
            'waypoint': [_number(v) for v in trajectory['position']],
            'yaws': [_number(s['trajectory']['yaw']) for s in steps]}


def pid_graph_nodes(mode='distributed'):
    """The node processes pid.launch starts in ``mode`` (the distributed PID framework's graph)."""
    root = ET.parse(paths.data_path('launch', 'pid.launch')).getroot()
    for group in root.iter('group'):
        if "mode_checked == '%s'" % mode in (group.get('if') or ''):
            return sum(1 for _ in group.iter('node'))
    return None


def batch_facts():
    """The context entries of these figures for ``templates/batch.md``."""
    return {'static_steps': static_steps(), 'pid_graph_nodes': pid_graph_nodes(), 'reanchor_lag': MAX_LAG,
            'paper_cpu_ratio': PAPER_CPU_RATIO}

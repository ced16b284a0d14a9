"""The paper's experiments as data: its controllers (and their names in tables and titles), scenario groups and
published simulation figures. The bottom room of the lab: every other room reads the paper from here."""
from anafi_control import registry

CONTROLLERS = registry.batch_names('paper')   # the paper's two (mpc, pid): every batch runs them
BEYOND = registry.batch_names('beyond')       # beyond the paper: a column where the batch has it
KNOWN_CONTROLLERS = CONTROLLERS + BEYOND
LABELS = registry.labels()                    # the controllers' names in tables and titles
STATIC = ('static_wp0', 'static_wp1')
STRAIGHT_SPEEDS = (1, 2, 3, 4, 5)
STRAIGHT = tuple('straight_%d' % v for v in STRAIGHT_SPEEDS)
CIRCLES = ((1, 1), (2, 1), (2, 2), (3, 1), (3, 2), (3, 3))          # (r [m], v [m/s]), Table 4
VERTICAL = ((1, 1), (2, 1), (2, 2))                                  # Table 5
CIRCLE_SCENARIOS = tuple('circle_r%d_v%d' % rv for rv in CIRCLES)
VERTICAL_SCENARIOS = tuple('vertical_r%d_v%d' % rv for rv in VERTICAL)
ALL_SCENARIOS = STATIC + STRAIGHT + CIRCLE_SCENARIOS + VERTICAL_SCENARIOS

PAPER_TABLE3 = {'mpc': (0.16, 0.36, 0.59, 0.82, 1.41), 'pid': (1.32, 2.67, 4.07, 5.32, 7.00)}
"""The paper's Table 3: mean tracking error [m] on the straight line at 1..5 m/s (simulation)."""

PAPER_CPU_RATIO = 2.59
"""The paper's computational workload: the PID framework's CPU time over the MPC's."""

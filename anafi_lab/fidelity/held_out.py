"""The held-out cells: what a comparison with Sphinx's runs of the paper's Tables 4 and 5 implies (pure, no ROS).

Sphinx's runs of the circles and the vertical periodic motions are held out of this repository. What is known of
them is a comparison (the data file ``held_out.yaml`` beside this module, installed with the package): an earlier
version of the stand-in, whose e_mu per cell is recorded (``COMPARED_E_MU``), was compared with them, and the ratio
of its e_mu to Sphinx's was stated as one range per group of cells (``RATIO_RANGES``). Each range bounds the Sphinx
value of every cell of its group, and so the ratio of any configuration's e_mu now to Sphinx's
(``held_out_bounds``, ``held_out_score``). A bound, not a measurement: the ranges are per group, and the compared
figures came from runs whose timer phases may differ from the recorded batch's.
"""
import collections
import math
import pkgutil

import numpy as np
import yaml

from anafi_lab.engine.replay import within
from anafi_lab import paper

RatioRange = collections.namedtuple('RatioRange', 'controller source scenarios range group inferred')
RatioRange.__doc__ = ('One stated range of the comparison: controller (pid|mpc), source (estimate|truth), the '
                      'scenarios of its group, range ((low, high) compared e_mu / Sphinx e_mu), group (what the '
                      'group is, in words), inferred (True: the range is not stated but follows from the cells '
                      'named as off: 1 -+ ``HELD_OUT_BAND``).')


def load_held_out(data=None):
    """The held-out data (``held_out.yaml`` of this package, or the YAML text ``data``): (band, compared batch,
    fast circles, {(controller, source): {scenario: compared e_mu [m]}}, (``RatioRange``, ...))."""
    raw = yaml.safe_load(data if data is not None else pkgutil.get_data('anafi_lab.fidelity', 'held_out.yaml'))
    band = float(raw['band'])
    fast = tuple(raw['fast_circles'])
    groups = {'held_out': paper.CIRCLE_SCENARIOS + paper.VERTICAL_SCENARIOS,
              'circles': tuple(paper.CIRCLE_SCENARIOS), 'vertical': tuple(paper.VERTICAL_SCENARIOS),
              'fast_circles': fast,
              'other_circles': tuple(s for s in paper.CIRCLE_SCENARIOS if s not in fast)}
    compared = collections.OrderedDict(((c, s), dict((k, float(v)) for k, v in cells.items()))
                                       for c, sources in raw['compared_e_mu'].items() for s, cells in sources.items())
    ranges = []
    for g in raw['ratio_ranges']:
        inferred = bool(g.get('inferred', False))
        lo, hi = (1.0 - band, 1.0 + band) if inferred else (float(g['range'][0]), float(g['range'][1]))
        ranges.append(RatioRange(g['controller'], g['source'], groups[g['scenarios']], (lo, hi), g['group'],
                                 inferred))
    return band, str(raw['compared_batch']), fast, compared, tuple(ranges)


HELD_OUT_BAND, COMPARED_BATCH, FAST_CIRCLES, COMPARED_E_MU, RATIO_RANGES = load_held_out()
HELD_OUT_SCENARIOS = paper.CIRCLE_SCENARIOS + paper.VERTICAL_SCENARIOS   # Tables 4 and 5: held out of the repo
HELD_OUT_CELLS = sum(len(g.scenarios) for g in RATIO_RANGES)
INFERRED_RANGE = [g.range for g in RATIO_RANGES if g.inferred][0]   # the other MPC circles vs the estimate


def held_out_bounds(records, variant, variant_pid=None):
    """What the comparison implies for each held-out cell of a configuration: [(controller, source, scenario,
    compared e_mu, (low, high) compared / Sphinx, (Sphinx low, high) [m], stand-in e_mu now, (low, mid, high)
    now / Sphinx, the group in words)], mid at the geometric middle of the stated range. ``records``:
    ``variants.scenario_runs`` output; ``variant`` names the MPC's runs, ``variant_pid`` the PID's (default the
    same)."""
    out = []
    for controller, source, scenarios, (lo, hi), group, _ in RATIO_RANGES:
        name = variant if controller == 'mpc' else (variant_pid or variant)
        key = 'e_mu' if source == 'estimate' else 'e_mu_truth'
        for scenario in scenarios:
            first = COMPARED_E_MU[(controller, source)][scenario]
            r = records.get((name, controller, scenario))
            now = r.get(key) if r and r.get('ok') else None
            sphinx = (first / hi, first / lo)
            mid = first / math.sqrt(lo * hi)
            ratio = ((now / sphinx[1], now / mid, now / sphinx[0]) if now is not None
                     else (float('nan'),) * 3)
            out.append((controller, source, scenario, first, (lo, hi), sphinx, now, ratio, group))
    return out


def held_out_score(records, variant, variant_pid=None, band=HELD_OUT_BAND):
    """(cells whose mid now / Sphinx lies within +-``band``, cells outside it, mean abs(ln(mid))) of a
    configuration's ``held_out_bounds``, over the cells that ran (``HELD_OUT_CELLS`` when all did)."""
    mids = [row[7][1] for row in held_out_bounds(records, variant, variant_pid) if math.isfinite(row[7][1])]
    inside = sum(1 for m in mids if within(m, band))
    return inside, len(mids) - inside, (float(np.mean([abs(math.log(m)) for m in mids])) if mids else float('nan'))

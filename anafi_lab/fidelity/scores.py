"""Scores of the fidelity runs (pure, no ROS): how many cells lie within a band of Sphinx's (or of the paper's
Table 3, or of the stand-in's own logs) and by how much they miss (mean or largest |ln ratio|).

- ``score`` / ``combined``: the shared-log replays of one configuration (``replay.replay_all`` records);
- ``table3_ratios`` / ``table3_score``: the engine's Table 3 runs against the paper's;
- ``self_replay_score``: the replay method on the stand-in's own runs (``variants.self_replay_runs``);
- ``fusion_gain_rows``: per gain of the position fusion its shared-log score and its held-out middles.
"""
import collections
import math

import numpy as np

from anafi_lab.fidelity.held_out import FAST_CIRCLES, HELD_OUT_BAND, HELD_OUT_CELLS, held_out_bounds, held_out_score
from anafi_lab.engine.replay import CELLS, within
from anafi_lab.fidelity.variants import FUSION_GAIN_ROLES
from anafi_lab import paper

BANDS = (0.10, 0.15, HELD_OUT_BAND)


def cell_key(cell):
    """The key of a (source, stat) cell in a record: 'estimate_e_mu' etc."""
    return '%s_%s' % cell


def record_ratios(record, key='ratio'):
    """[(log, cell, ratio)] of a replay record (ratio None when missing); ``key`` 'ratio' (whole log) or
    'ratio_late' (after ``replay.LATE``)."""
    ratios = record.get(key) or {}
    return [(record['log'], cell, ratios.get(cell_key(cell))) for cell in CELLS]


def combined(records, models, mpc_variant, pid_variant):
    """Records of one configuration: the PID logs from ``pid_variant``, the MPC logs from ``mpc_variant``
    (a timing option of the MPC does not change the PID runs); [record]."""
    out = []
    for (log, variant), rec in records.items():
        want = mpc_variant if rec['controller'] == 'mpc' else pid_variant
        if variant == want and log in models:
            out.append(rec)
    return out


def score(records, band=BANDS[0], key='ratio'):
    """(cells within ``band``, cells with a ratio, mean |ln ratio|) over replay records (``record_ratios``)."""
    ratios = [r for rec in records for _, _, r in record_ratios(rec, key) if r is not None and r > 0]
    inside = sum(1 for r in ratios if within(r, band))
    return inside, len(ratios), (float(np.mean([abs(math.log(r)) for r in ratios])) if ratios else float('nan'))


def table3_ratios(records, variant):
    """{(controller, speed): stand-in e_mu / paper's Table 3} of one variant."""
    out = collections.OrderedDict()
    for c in paper.CONTROLLERS:
        for k, published in enumerate(paper.PAPER_TABLE3[c]):
            r = records.get((variant, c, k + 1))
            v = r.get('e_mu') if r else None
            out[(c, k + 1)] = (v / published) if v is not None else float('nan')
    return out


def table3_score(t3, pid_v, mpc_v, band=BANDS[0]):
    """(cells of Table 3 within ``band``, cells, mean |ln ratio|) of a configuration."""
    ratios = []
    for c in paper.CONTROLLERS:
        for k, published in enumerate(paper.PAPER_TABLE3[c]):
            r = t3.get((mpc_v if c == 'mpc' else pid_v, c, k + 1))
            if r and r.get('ok') and r.get('e_mu'):
                ratios.append(r['e_mu'] / published)
    inside = sum(1 for r in ratios if within(r, band))
    return inside, len(ratios), (float(np.mean([abs(math.log(r)) for r in ratios])) if ratios else float('nan'))


def self_replay_score(records, variant, band=None, key='ratio', scenarios=None):
    """(cells within +-``band`` (default BANDS[0]), cells with a ratio, max abs ln ratio) of a variant's
    self-replays (``key`` 'ratio' or 'ratio_latency'; ``scenarios``: only those, default all)."""
    band = BANDS[0] if band is None else band
    ratios = [x for (v, _, s), r in records.items() if v == variant and r.get('ok')
              and (scenarios is None or s in scenarios)
              for x in (r.get(key) or {}).values() if x is not None and x > 0]
    inside = sum(1 for x in ratios if within(x, band))
    return inside, len(ratios), (max(abs(math.log(x)) for x in ratios) if ratios else float('nan'))


FusionGainRow = collections.namedtuple('FusionGainRow', 'role label profile shared held fast truth')


def fusion_gain_rows(records, scen, entries, logs):
    """``FusionGainRow`` per ``entries`` item (role, label, ``estimate.FusionProfileRow``, variant name): that
    variant's replays of ``logs`` (``records``) and held-out runs (``scen``, ``scenario_runs`` records)."""
    out = []
    for role, label, row, name in entries:
        if role not in FUSION_GAIN_ROLES:
            raise ValueError('fusion_gain_rows: unknown role %r' % (role,))
        held = held_out_score(scen, name)
        bounds = held_out_bounds(scen, name)
        fast = collections.OrderedDict((b[2], b[7][1]) for b in bounds
                                       if b[0] == 'mpc' and b[1] == 'estimate' and b[2] in FAST_CIRCLES)
        truth = collections.OrderedDict((b[2], b[7][1]) for b in bounds if b[0] == 'mpc' and b[1] == 'truth')
        out.append(FusionGainRow(role, label, row, score(combined(records, logs, name, name)),
                                 held if held[0] + held[1] == HELD_OUT_CELLS else None, fast, truth))
    return out

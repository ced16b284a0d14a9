"""A fleet's summary when it stops: one table, one row per drone (pure, no ROS).

Stage: experiments (beside mission/fleet.py). When a fleet's roslaunch has ended (Ctrl-C, or by itself), the
fleet launcher (anafi_sim/nodes/fleet_launcher.py) prints ``summary_table``: per drone its controller, the state
of its evaluation (``final``: the measured segment ended; ``incomplete``: stopped before; ``waiting``: nothing
measured yet), the samples and e_mu / e_max [m] against the estimate (the paper's metric) and the ground truth,
read from the evaluator's summary file ``<out_dir>/<drone>.yaml`` (``read_summary``). A drone without an
evaluator (``evaluate:=false``) or whose file is missing, unreadable or older than the fleet's start says so in
its row.
"""
import os

import yaml

COLUMNS = ('drone', 'controller', 'state', 'samples', 'e_mu est [m]', 'e_max est [m]', 'e_mu truth [m]',
           'e_max truth [m]')


def summary_path(out_dir, drone):
    """Where a fleet's evaluator writes the drone's summary (anafi_sim.mission.fleet.launch_xml)."""
    return os.path.join(out_dir, '%s.yaml' % drone)


def read_summary(path, since=None):
    """(summary dict, None) of the evaluator's summary file at ``path``, or (None, why) when it is missing,
    unreadable, not a summary, or last written before ``since`` (a time.time(): a file of an earlier run)."""
    try:
        if since is not None and os.path.getmtime(path) < since:
            return None, 'no summary of this run (%s is older)' % os.path.basename(path)
        with open(path) as f:
            data = yaml.safe_load(f)
    except (IOError, OSError):
        return None, 'no summary written'
    except yaml.YAMLError as error:
        return None, 'unreadable summary: %s' % str(error).splitlines()[0]
    if not isinstance(data, dict) or 'state' not in data:
        return None, 'not an evaluation summary'
    return data, None


def _metric(summary, source, key):
    part = summary.get(source)
    value = part.get(key) if isinstance(part, dict) else None
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return '-'
    return '%.3f' % value


def summary_row(drone, controller, summary, why=None):
    """One row (a tuple of COLUMNS' texts) of a drone: its summary dict, or None and ``why`` (the state column)."""
    if summary is None:
        return (drone, controller, why or 'no summary', '-', '-', '-', '-', '-')
    samples = summary.get('samples')
    return (drone, controller, str(summary.get('state', '?')),
            str(samples) if isinstance(samples, int) and not isinstance(samples, bool) else '-',
            _metric(summary, 'estimate', 'e_mu'), _metric(summary, 'estimate', 'e_max'),
            _metric(summary, 'truth', 'e_mu'), _metric(summary, 'truth', 'e_max'))


def summary_table(title, rows):
    """The table's text: a title line, then COLUMNS and ``rows`` aligned (plain text, one line each)."""
    table = [COLUMNS] + [tuple(r) for r in rows]
    widths = [max(len(r[i]) for r in table) for i in range(len(COLUMNS))]

    def line(cells):
        return '  '.join(c.ljust(w) for c, w in zip(cells, widths)).rstrip()
    out = [title, line(COLUMNS), line(['-' * w for w in widths])]
    out += [line(r) for r in table[1:]]
    return '\n'.join(out) + '\n'


def fleet_summary(fleet_name, drones, out_dir, evaluate=True, since=None, reason='stopped'):
    """The summary table of a fleet that ended: ``drones`` [(name, controller)], each drone's evaluator summary
    read from ``out_dir`` (``evaluate`` False: none ran); ``since``: the fleet's start (older files are not
    this run's); ``reason``: how it ended, for the title."""
    rows = []
    for name, controller in drones:
        if evaluate:
            summary, why = read_summary(summary_path(out_dir, name), since)
        else:
            summary, why = None, 'not evaluated (evaluate:=false)'
        rows.append(summary_row(name, controller, summary, why))
    title = 'fleet %s %s: %d drone%s (evaluations in %s)' % (fleet_name, reason, len(rows),
                                                             '' if len(rows) == 1 else 's', out_dir)
    return summary_table(title, rows)

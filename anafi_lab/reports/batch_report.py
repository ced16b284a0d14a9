"""The paper's batch in-process with its report: every scenario of the paper with both controllers ->
``out_dir/experiments.yaml`` (``{'meta', 'records'}``, the schema of the ROS batch), ``out_dir/report.md``
(``anafi_lab.reports.paper_tables``: the paper's tables) and the plots (one per run, drawn by the run's worker,
and the static waypoints' comparison, ``anafi_sim.mission.plots``).

Stage: report (on top of ``anafi_lab.engine.runs``; used by anafi_lab/cli/experiment.py batch).
"""
import collections
import datetime
import os
import sys
import time

from anafi_lab import paper
from anafi_lab.engine.runs import batch_tasks, cost, execute
from anafi_lab.reports import paper_tables
from anafi_sim import processes, run_files


def static_comparison(records, plots_dir, report_dir):
    """The static waypoints' comparison plot (Fig. 6 style) from the runs' CSVs: [(title, relative path)]."""
    from anafi_sim.mission import plots
    static = [r for r in records if r['scenario'] in paper.STATIC and r.get('ok')
              and os.path.exists((r.get('files') or {}).get('csv') or '')]
    if not static:
        return []
    runs = []
    for rec in sorted(static, key=lambda r: (r['scenario'], r['controller'] != 'pid')):
        window = plots.summary_window(rec['summary'])
        runs.append(('%s %s' % (paper.LABELS.get(rec['controller'], rec['controller']),
                                'WP0' if rec['scenario'].endswith('0') else 'WP1'),
                     rec['files']['csv'], window[0] if window else 0.0))
    path = os.path.join(plots_dir, 'static_waypoints.png')
    plots.plot_comparison(runs, path, title='Static waypoints WP0 / WP1 from hover (cf. Fig. 6); t = 0 at the step')
    return [(paper_tables.STATIC_COMPARISON, os.path.relpath(path, report_dir))]


def batch(out_dir, scenarios=paper.ALL_SCENARIOS, controllers=paper.CONTROLLERS, workers=None, scheduler=None,
          runs_dir=None, plots=True, command='', progress=None, seed=None, schedule=None, conditions=None):
    """The paper's batch in-process (see the module doc); returns (records, meta, report path)."""
    out_dir = os.path.abspath(out_dir)
    runs_dir = os.path.abspath(runs_dir or os.path.join(out_dir, 'runs'))
    plots_dir = os.path.join(out_dir, 'plots')
    for d in (out_dir, runs_dir) + ((plots_dir,) if plots else ()):
        os.makedirs(d, exist_ok=True)
    workers = workers or os.cpu_count() or 1
    tasks = batch_tasks(scenarios, controllers, runs_dir, plots_dir if plots else None, seed, schedule, conditions)
    order = sorted(range(len(tasks)), key=lambda i: -cost(tasks[i]))
    load = processes.load_average()      # the machine's load before the batch (its own work comes on top)
    t0 = time.perf_counter()
    records = execute(tasks, workers=workers, scheduler=scheduler, progress=progress, label='batch', order=order)
    wall = time.perf_counter() - t0
    plot_list, comparisons = [], []
    for rec in records:
        path = (rec.get('files') or {}).get('plot')
        if path:
            rec['plot'] = os.path.relpath(path, out_dir)
            plot_list.append(('%s_%s' % (rec['scenario'], rec['controller']), rec['plot']))
    if plots:
        try:
            comparisons = static_comparison(records, plots_dir, out_dir)
        except (IOError, OSError, ValueError) as error:
            sys.stderr.write('static comparison plot failed: %s\n' % error)
    sim = sum((r.get('info') or {}).get('sim_s') or 0.0 for r in records)
    meta = collections.OrderedDict([
        ('command', command or 'anafi_lab/cli/experiment.py batch'),
        ('date', datetime.datetime.now().strftime('%Y-%m-%d %H:%M')),
        ('machine', processes.machine(load)),
        ('engine', 'inprocess'),
        ('rtf', 'none (virtual time)'), ('wall_s', round(wall, 1)), ('mirror', 'no (in-process engine)'),
        ('pid_mode', 'distributed'), ('conditions', conditions or 'none (sim.yaml: no wind)'),
        ('workers', 'the Dask scheduler %s' % scheduler if scheduler else '%d worker process(es)' % workers),
        ('sim_s', round(sim, 1)), ('batch_rtf', round(sim / wall, 1) if wall > 0 else None),
        ('notes', ['- In-process engine (anafi_lab/engine/engine.py): one process per run, virtual time, the '
                   'cores of the ROS graph on its schedule (rates, phases, transport delays: the engine\'s '
                   'DEFAULT_SCHEDULE); "achieved RTF" is simulated seconds per wall second of the run; the '
                   'simulator cannot fall behind, so there are no overruns, re-anchors or start-up wall times.',
                   '- %d runs on %s: %.1f s wall for %.0f s of simulated time.' % (
                       len(records), 'Dask scheduler %s' % scheduler if scheduler else '%d worker process(es)'
                       % workers, wall, sim),
                   '- Flight conditions: %s.' % (conditions or 'none (sim.yaml: no wind, as Sphinx flew)'),
                   '- Controller CPU: the time spent in the controller\'s callbacks within one process; the ROS '
                   'batch counts whole node processes (the distributed PID\'s 8 nodes pay ROS\'s per-message cost), '
                   'so the PID / MPC ratio here is not the paper\'s measure.']),
    ])
    report_path = os.path.join(out_dir, 'paper.md')
    with open(report_path, 'w') as stream:
        stream.write(paper_tables.render(records, meta, plot_list, comparisons))
    run_files.write_yaml(os.path.join(out_dir, 'experiments.yaml'), {'meta': dict(meta), 'records': records})
    return records, meta, report_path

"""Many in-process runs: one run's files, the paper's batch of tasks, and the executors that spread runs over
processes or a Dask cluster (pure, no ROS).

Stage: experiments (on top of ``anafi_lab.engine.engine``; used by anafi_lab/cli/experiment.py
and ``anafi_lab.engine.sweep``; the batch's report ``anafi_lab.reports.batch_report``).

- A *task* is a plain dict (``make_task``: scenario, controller, seed, wind, params, schedule, state_source,
  name, and where to write files), so it pickles to any worker; ``run_task(task)`` runs it and returns its
  *record*: the batch record of benchmarks/results/experiments.yaml (scenario, controller, ok, error,
  summary = the evaluator's dict, info = run figures, step = static-waypoint step metrics, wall_s, files,
  plot). With ``out_dir`` it writes ``<name>.yaml`` (the summary), ``<name>.csv`` (the reference log of the
  whole run, as the evaluator's ``csv_window: all``) and, with ``plot``, ``<name>.png``.
- ``execute(tasks, workers, scheduler)`` runs tasks serially (1 worker), on a ``ProcessPoolExecutor``
  (``workers`` processes) or on a Dask distributed cluster (``scheduler``: its address; the same tasks
  through ``distributed.Client(address).get_executor()``); records come back in task order; progress as a
  tqdm bar on a terminal, else one line per finished run.
- ``batch_tasks(...)``: every scenario of the paper with both controllers (the batch with its report:
  ``anafi_lab.reports.batch_report``).
"""
import collections
import os
import sys
import time

from anafi_lab import paper
from anafi_sim.mission import step_response
from anafi_lab.engine.engine import Engine
from anafi_sim.mission.reference_log import write_log
from anafi_sim.mission.trajectory import load_scenario
from anafi_sim import run_files
from anafi_sim.numeric import fmt

SYNC_SCHEDULE = collections.OrderedDict([('controller_phase', 0.0), ('generator_phase', 0.005), ('mpc_latency', 0.0)])
"""Engine schedule overrides (``anafi_lab.engine.engine.DEFAULT_SCHEDULE``) of a ROS run in lockstep
(experiment.launch sync:=true): simulation time is held at 0 while the nodes start, so the controllers'
timers run at 0.1 s multiples (controller_phase 0; the distributed PID's timers are at phase 0 by default);
the trajectory generator starts its loop on the first /clock tick, held for a second (one physics step,
5 ms); the simulator waits at the controller's tick for its command and applies it from that tick on (no
command latency in simulation time: mpc_latency 0)."""

TASK_DEFAULTS = collections.OrderedDict([
    ('scenario', None), ('controller', 'mpc'), ('seed', None), ('wind', None), ('params', None),
    ('schedule', None), ('state_source', 'estimate'), ('name', None), ('out_dir', None), ('plot', False),
    ('detail', True), ('conditions', None), ('plot_format', None), ('plot_dpi', None),
])


def make_task(scenario, controller='mpc', **kwargs):
    """A task dict (keys ``TASK_DEFAULTS``); ``detail`` False keeps only the summary and key figures."""
    unknown = sorted(set(kwargs) - set(TASK_DEFAULTS))
    if unknown:
        raise ValueError('unknown task key(s): %s' % ', '.join(unknown))
    task = collections.OrderedDict(TASK_DEFAULTS)
    task.update(scenario=scenario, controller=controller)
    task.update(kwargs)
    return dict(task)


def task_name(task):
    """The run's name: the task's ``name`` or SCENARIO_CONTROLLER (scenario file name without .yaml)."""
    if task.get('name'):
        return task['name']
    scenario = os.path.splitext(os.path.basename(str(task['scenario'])))[0]
    return '%s_%s' % (scenario, str(task['controller']).split(':')[-1])



def run_task(task):
    """Run one task (see the module doc); returns its record (plain data, picklable)."""
    name = task_name(task)
    t0 = time.perf_counter()
    record = collections.OrderedDict([('scenario', None), ('controller', task['controller']), ('ok', False),
                                      ('error', '')])
    try:
        scenario = load_scenario(task['scenario'])
        record['scenario'] = scenario.name if os.sep not in str(task['scenario']) else str(task['scenario'])
        engine = Engine(scenario, task['controller'], seed=task.get('seed'), wind=task.get('wind'),
                        controller_params=task.get('params'), schedule=task.get('schedule'),
                        state_source=task.get('state_source') or 'estimate', name=name,
                        conditions=task.get('conditions'))
        result = engine.run()
    except Exception as error:      # a bad task must not take the batch down: the record says why
        record['error'] = '%s: %s' % (type(error).__name__, error)
        record.update(summary=None, info=None, step=None, wall_s=round(time.perf_counter() - t0, 3), files={},
                      plot='')
        return dict(record)
    record['scenario'] = scenario.name
    record['ok'] = result.ok
    record['error'] = result.error
    record['summary'] = result.summary
    info = result.info
    if not task.get('detail', True):
        info = dict((k, info[k]) for k in ('engine', 'state', 'seed', 'wind', 'conditions', 'sim_s',
                                           'scenario_sim_s', 'wall_s', 'achieved_rtf', 'hover_commands',
                                           'controller_cpu_s'))
    record['info'] = info
    record['step'] = None
    files = {}
    out_dir = task.get('out_dir')
    if out_dir:
        if not os.path.isdir(out_dir):
            os.makedirs(out_dir, exist_ok=True)
        files['summary'] = os.path.join(out_dir, name + '.yaml')
        run_files.write_yaml(files['summary'], result.summary)
        if result.evaluation is not None:
            files['csv'] = os.path.join(out_dir, name + '.csv')
            write_log(files['csv'], result.evaluation.full_log)
    if result.ok and scenario.name.startswith('static') and result.evaluation is not None:
        from anafi_sim.mission.plots import summary_window
        try:
            record['step'] = step_response.as_dict(step_response.step_metrics(result.evaluation.full_log,
                                                                               summary_window(result.summary)))
        except (ValueError, TypeError) as error:
            record['error'] = 'step metrics: %s' % error
    record['plot'] = ''
    if task.get('plot') and files.get('csv'):
        plot_dir = task['plot'] if isinstance(task['plot'], str) else out_dir
        path = os.path.join(plot_dir, name + '.' + (task.get('plot_format') or run_files.FIGURE_FORMATS[0]))
        try:
            from anafi_sim.mission.plots import plot_run
            from anafi_sim.mission.run_end import run_title
            title = '%s, %s' % (scenario.name, paper.LABELS.get(task['controller'], task['controller']))
            plot_run(files['csv'], path, summary=result.summary, title=run_title(title, task.get('conditions') or ''),
                     wind=engine.settings, dpi=task.get('plot_dpi') or run_files.FIGURE_DPI)
            files['plot'] = path
        except (IOError, OSError, ValueError) as error:
            record['error'] = record['error'] or 'plot: %s' % error
    record['wall_s'] = round(time.perf_counter() - t0, 3)
    record['files'] = files
    record['leftover_processes'] = []
    record['attempts'] = 1
    record['earlier_attempts'] = []
    return dict(record)


def result_line(record, name=None):
    """One line: RESULT name ok|FAILED e_mu / e_max / e_sigma vs estimate and truth [m], rtf, files."""
    summary = record.get('summary') or {}
    est, tru = summary.get('estimate') or {}, summary.get('truth') or {}
    info = record.get('info') or {}
    parts = ['RESULT %s' % (name or summary.get('name') or '%s_%s' % (record.get('scenario'),
                                                                        record.get('controller'))),
             'ok' if record.get('ok') else 'FAILED (%s)' % record.get('error'),
             'e_mu %s e_max %s e_sigma %s m (estimate)' % tuple(fmt(est.get(k), 4)
                                                               for k in ('e_mu', 'e_max', 'e_sigma')),
             'e_mu %s m (truth)' % fmt(tru.get('e_mu'), 4),
             'samples %s' % summary.get('samples'),
             'sim %s s in %s s wall (rtf %s)' % (fmt(info.get('sim_s'), 1), fmt(info.get('wall_s'), 2),
                                                 fmt(info.get('achieved_rtf'), 1))]
    return '  '.join(parts)


# ---------------------------------------------------------------------------------------------- executors
def eta(elapsed, done, total):
    """Time left [m:ss or h:mm:ss] when ``done`` of ``total`` runs took ``elapsed`` s (the mean pace so far, as
    tqdm estimates it); '?' before the first run, '0:00' at the end."""
    if done <= 0 or not elapsed >= 0.0:
        return '?'
    left = int(round(elapsed / done * max(0, total - done)))
    hours, rest = divmod(left, 3600)
    return ('%d:%02d:%02d' % (hours, rest // 60, rest % 60)) if hours else '%d:%02d' % (rest // 60, rest % 60)


class Progress(object):
    """A tqdm bar when ``stream`` is a terminal (and tqdm is installed: its ETA), else one line per finished run
    (elapsed time and ETA, ``eta``)."""

    def __init__(self, total, label='runs', stream=None, bar=None):
        self.total, self.label = total, label
        self.stream = stream or sys.stderr
        self.done = 0
        self.t0 = time.monotonic()
        self.bar = None
        if bar is None:
            bar = hasattr(self.stream, 'isatty') and self.stream.isatty()
        if bar:
            try:
                from tqdm import tqdm
                self.bar = tqdm(total=total, desc=label, file=self.stream, unit='run', dynamic_ncols=True)
            except ImportError:
                self.bar = None

    def update(self, record):
        self.done += 1
        if self.bar is not None:
            est = ((record.get('summary') or {}).get('estimate') or {}).get('e_mu')
            self.bar.set_postfix_str('%s_%s e_mu %s' % (record.get('scenario'), record.get('controller'),
                                                        fmt(est, 3)))
            self.bar.update(1)
            return
        est = ((record.get('summary') or {}).get('estimate') or {})
        info = record.get('info') or {}
        elapsed = time.monotonic() - self.t0
        self.stream.write('[%7.1f s, ETA %s] %*d/%d %-24s %s  e_mu %s m  (%s s, rtf %s)%s\n' % (
            elapsed, eta(elapsed, self.done, self.total), len(str(self.total)), self.done, self.total,
            (record.get('name') or (record.get('summary') or {}).get('name')
             or '%s_%s' % (record.get('scenario'), record.get('controller'))),
            'ok    ' if record.get('ok') else 'FAILED', fmt(est.get('e_mu'), 4),
            fmt(record.get('wall_s'), 2), fmt(info.get('achieved_rtf'), 0),
            '' if record.get('ok') else '  ' + str(record.get('error'))))
        self.stream.flush()

    def close(self):
        if self.bar is not None:
            self.bar.close()


def _dask_executor(scheduler):
    """(executor, closer) of a Dask distributed cluster: ``scheduler`` is an address, or a Client."""
    try:
        import distributed
    except ImportError:
        raise RuntimeError('--scheduler needs Dask distributed (Debian: apt-get install python3-distributed)')
    client = scheduler if isinstance(scheduler, distributed.Client) else distributed.Client(scheduler)
    close = (lambda: None) if client is scheduler else client.close
    return client.get_executor(), close


def execute(tasks, workers=1, scheduler=None, progress=None, label='runs', function=run_task, order=None):
    """Run ``function(task)`` for every task; returns the results in task order.

    workers: processes (1 = in this process, no pool); scheduler: a Dask scheduler address (or Client): the
    tasks go to that cluster instead; progress: a ``Progress`` (default: one on stderr); order: indices in
    the order to submit (default: as given; the batch submits its longest runs first).
    """
    import concurrent.futures as cf
    tasks = list(tasks)
    results = [None] * len(tasks)
    own_progress = progress is None
    progress = progress or Progress(len(tasks), label)
    order = list(range(len(tasks))) if order is None else list(order)
    try:
        if scheduler is None and workers <= 1:
            for i in order:
                results[i] = function(tasks[i])
                progress.update(results[i])
            return results
        if scheduler is not None:
            executor, close = _dask_executor(scheduler)
        else:
            executor = cf.ProcessPoolExecutor(max_workers=int(workers))
            close = executor.shutdown
        try:
            futures = dict((executor.submit(function, tasks[i]), i) for i in order)
            for future in cf.as_completed(futures):
                i = futures[future]
                results[i] = future.result()
                progress.update(results[i])
        finally:
            close()
    finally:
        if own_progress:
            progress.close()
    return results


# ---------------------------------------------------------------------------------------------- batch
def batch_tasks(scenarios=paper.ALL_SCENARIOS, controllers=paper.CONTROLLERS, runs_dir=None, plots_dir=None,
                seed=None, schedule=None, conditions=None):
    """The batch's tasks: every scenario x controller (scenario-major, as the ROS batch orders them)."""
    return [make_task(s, c, seed=seed, schedule=schedule, out_dir=runs_dir, plot=plots_dir or False,
                      conditions=conditions)
            for s in scenarios for c in controllers]


def cost(task):
    """Rough relative cost of a task: simulated seconds, x3 for the MPC (its solves dominate)."""
    try:
        duration = load_scenario(task['scenario']).duration
    except ValueError:
        duration = 0.0
    return duration * (3.0 if task['controller'] == 'mpc' else 1.0)

"""The end of one experiment run (pure Python, no ROS): its files checked, plotted, written, named, reported.

Stage: experiment orchestration, after anafi_sim.mission.monitor (which decides when the run ends). Used by
the experiment monitor node (anafi_sim/nodes/experiment_monitor.py) once the evaluator has written its files.
A run's files are given as ``{key: path}`` for the keys of ``RUN_FILES`` ('' = not written by this run):

- ``finish_run`` checks the evaluator's files (``evaluator_file_problems``), draws the plot from the CSV,
  writes the run file (``info``, YAML), and when the run failed renames every file it left to its FAILED name
  (anafi_sim.run_files.failed_name; the bag's recorder renames the bag itself). A run that reached its end
  but whose files are missing or not final fails here, with the reason;
- ``result_lines`` is the RESULT block printed at the end (the label, ok or FAILED with the reason, a live
  tuning change inside the measured window, the errors, the simulation and MPC figures, the files);
- ``conditions_info`` / ``run_title``: the flight conditions a run flew in, for its run file and its figure's
  title (a windy run never reads as a calm one).
"""
import collections
import os

from anafi_sim import run_files
from anafi_sim.mission.monitor import FAILED, reader_line, result_status, summary_lines
from anafi_sim.sim.conditions_profile import conditions_label

#: a run's files, in the order the RESULT block names them
RUN_FILES = ('bag', 'csv', 'summary', 'plot', 'info')
#: the files the monitor renames when the run failed (the recorder renames the bag)
MARKED_FILES = ('summary', 'csv', 'plot', 'info')

FinishedRun = collections.namedtuple('FinishedRun', 'ok info files problems errors')
"""What ``finish_run`` did: ``ok`` (the run measured and its files are written), ``info`` (the run file's
data: state and reason FAILED when it failed here), ``files`` (every key of the input, FAILED names for the
renamed files and the bag of a failed run), ``problems`` (why a run that reached its end failed: files
missing, not final, the plot not drawn), ``errors`` (file operations that failed, for the node's log)."""


def conditions_info(name, settings=None):
    """The run file's ``conditions``: the profile's ``name`` ('none' without one; a path's file name) and the
    simulator ``settings`` it set (wind_x, ..., {} when none or unreadable)."""
    return {'name': conditions_label(name), 'settings': dict((str(k), v) for k, v in (settings or {}).items())}


def run_title(label, conditions=''):
    """The run's title: ``label``, with its conditions' name appended in parentheses unless ``label`` already
    names them (experiment.launch's default run name ends with them)."""
    name = conditions_label(conditions)
    if not conditions or name in str(label):
        return str(label)
    return '%s (%s)' % (label, name)


def evaluator_file_problems(files):
    """Problems with the evaluator's and the recorder's files (not written, e.g. a full disk, or not final)."""
    out = []
    path = files.get('summary')
    if path:
        data = run_files.read_yaml(path, tolerant=True)
        if not isinstance(data, dict) or data.get('state') != 'final':
            out.append('summary %s %s' % (path, 'not written' if not os.path.exists(path)
                                          else 'unreadable or not final'))
    if files.get('csv') and not os.path.isfile(files['csv']):
        out.append('CSV %s not written' % files['csv'])
    bag = files.get('bag')
    if bag and not os.path.exists(bag + '.active') and not os.path.exists(bag):
        out.append('bag %s not being recorded (rosbag stopped)' % bag)
    if out:
        out[-1] += ' (a full disk? see the nodes\' logs)'
    return out


def finish_run(ok, info, files, plot, problem=None):
    """The run's files once it ended; returns a ``FinishedRun``.

    ``ok``: the run reached its end (the evaluator's summary is final); ``info``: the run file's data
    (ExperimentMonitor.run_info() and what the node adds; 'reason' says why a failed run failed);
    ``files``: {key of RUN_FILES: path or ''}; ``problem``: why the measurement is no measurement
    (ExperimentMonitor.result_problem(), None when it is one); ``plot(csv_path, out_path, failed)`` draws the
    run's plot from its CSV (when there is a plot file and a CSV) into ``out_path`` (a temporary name with the
    plot file's extension: the format), ``failed`` = why the run failed (its title says FAILED) or None. Neither
    ``info`` nor ``files`` is changed.
    """
    info, files = dict(info), dict((k, files.get(k) or '') for k in RUN_FILES)
    problems, errors = [], []
    if ok:
        problems += [problem] if problem else []
        problems += evaluator_file_problems(files)
    if files['plot'] and files['csv'] and os.path.isfile(files['csv']):
        failed = None if ok and not problems else (
            '; '.join(problems) if ok else str(info.get('reason') or 'unknown'))
        try:
            with run_files.atomic_path(files['plot'], os.path.splitext(files['plot'])[1] or '.png') as tmp:
                plot(files['csv'], tmp, failed)
            info['plot'] = files['plot']
        except Exception as e:    # a plot that cannot be written: the run's files are not complete
            problems.append('plot %s not written: %s' % (files['plot'], e))
    elif ok and files['plot']:
        problems.append('no CSV %s: no plot' % files['csv'])
    if ok and problems:
        ok = False
        info['state'], info['reason'] = FAILED, '; '.join(problems)
    if files['info']:
        try:
            run_files.write_yaml(files['info'], info)
        except (IOError, OSError) as e:
            ok = False
            info['state'] = FAILED
            info['reason'] = '; '.join(r for r in (info.get('reason'), 'cannot write %s: %s'
                                                   % (files['info'], e)) if r)
    if ok and files['info']:
        try:
            os.remove(run_files.failed_name(files['info']))    # the "running" marker
        except OSError:
            pass
    if not ok:      # every file this run leaves says so in its name (the recorder renames the bag)
        try:
            marked = run_files.mark_failed([files[k] for k in MARKED_FILES], FAILED, info.get('reason'))
        except OSError as e:
            marked = []
            errors.append('cannot mark the files of the failed run: %s' % e)
        for key in RUN_FILES:
            if files[key]:
                failed = run_files.failed_name(files[key])
                if failed in marked or key == 'bag':
                    files[key] = failed
    return FinishedRun(ok, info, files, problems, errors)


def result_lines(finished, summary, label, run_dir=''):
    """The RESULT block of a finished run (``finish_run``'s result) with the evaluator's ``summary``."""
    info, files = finished.info, finished.files
    lines = ['', '=' * 78, 'RESULT %s  (%s)' % (label, result_status(finished.ok, info))]
    lines += summary_lines(summary, label)[1:] if summary else ['  no evaluator summary']
    if info.get('achieved_rtf') is not None:
        lines.append('  simulation: %.1f s in %.1f s wall (real-time factor %.2f), simulator overruns %s, '
                     're-anchors %s' % (info['scenario_sim_s'], info['scenario_wall_s'], info['achieved_rtf'],
                                        info['sim_overruns'], info['sim_reanchors']))
    if reader_line(info):
        lines.append(reader_line(info))
    if info.get('mpc_solve_time_mean_ms') is not None:
        lines.append('  MPC solve time: mean %.2f ms, max %.2f ms' % (info['mpc_solve_time_mean_ms'],
                                                                      info['mpc_solve_time_max_ms']))
    if run_dir:
        lines.append('  %-8s %s' % ('folder:', run_dir))
    for key in RUN_FILES:
        path = files[key]
        if path and (key in ('info', 'bag') or os.path.exists(path)):
            lines.append('  %-8s %s' % (key + ':', path))
    lines.append('=' * 78)
    return lines

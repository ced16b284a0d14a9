"""anafi_sim.mission.plots: run and comparison figures from reference-log CSV files (Agg, no display)."""
import math
import os

import numpy as np
import pytest

from anafi_sim import paths
from anafi_sim.mission import plots
from anafi_sim.mission.reference_log import write_log
from experiment_logs import make_log

REFERENCE_LOGS = paths.reference_logs_dir()     # shipped with the package
PNG_MAGIC = b'\x89PNG\r\n\x1a\n'


def circle_log(n=600, lag=0.3):
    t = np.arange(n) * (1.0 / 30.0)
    a = t / 2.0                                   # r = 2, v = 1 -> w = 0.5 rad/s
    wp = np.column_stack([2 * np.cos(a), 2 * np.sin(a), np.full(n, 5.0)])
    est = np.column_stack([2 * np.cos(a - lag), 2 * np.sin(a - lag), np.full(n, 5.0)])
    return t, make_log(t, est, wp, truth=est + 0.01)


def static_log(n=400):
    t = np.arange(n) * 0.05
    wp = np.where((t >= 5.0)[:, None], [3.0, 2.0, 5.0], [0.0, 0.0, 1.0])
    frac = np.clip(1 - np.exp(-np.clip(t - 5.0, 0, None) / 0.8), 0, 1)
    est = np.array([0.0, 0.0, 1.0]) + np.outer(frac, [3.0, 2.0, 4.0])
    return t, make_log(t, est, wp)


def test_moves_in_plane_tells_circles_from_steps():
    _, circle = circle_log()
    t, step = static_log()
    assert plots.moves_in_plane(circle)
    assert plots.moves_in_plane(circle, window=(5.0, 15.0))
    # a step into the window is not planar motion; the waypoint never spans x and y afterwards
    assert not plots.moves_in_plane(step, window=(5.0, t[-1]))
    assert not plots.moves_in_plane(step, window=(10.0, t[-1]))


def test_window_mask_and_summary_window():
    t = np.array([0.0, 1.0, 2.0, 3.0])
    assert plots.window_mask(t, (1.0, 2.0)).tolist() == [False, True, True, False]
    assert plots.window_mask(t, None).all()
    assert plots.summary_window({'window': [1.5, 3.0]}) == (1.5, 3.0)
    assert plots.summary_window({'window': [3.0, 1.0]}) is None
    assert plots.summary_window({'window': None}) is None
    assert plots.summary_window(None) is None


def test_plot_run_writes_a_small_png_from_the_csv(tmp_path):
    _, log = circle_log()
    csv = str(tmp_path / 'run.csv')
    write_log(csv, log)
    png = str(tmp_path / 'sub' / 'run.png')
    out = plots.plot_run(csv, png, summary={'name': 'circle', 'window': [5.0, 17.0]})
    assert out == png
    with open(png, 'rb') as f:
        data = f.read()
    assert data[:8] == PNG_MAGIC
    assert 5000 < len(data) < 150000
    # a figure with the xy path (the waypoint moves in x and y) has 5 axes, the yaw variant too
    fig = plots.run_figure(plots.load(csv), window=(5.0, 17.0), title='x')
    titles = [ax.get_title() for ax in fig.axes]
    assert any('xy path' in ti for ti in titles)
    _, step = static_log()
    fig = plots.run_figure(step, window=(5.0, 19.9))
    assert any(ti == 'yaw' for ti in [ax.get_title() for ax in fig.axes])


def test_error_line_is_the_mean_over_the_window():
    t, log = circle_log(lag=0.3)
    fig = plots.run_figure(log, window=(2.0, 10.0))
    err_ax = fig.axes[-1]
    labels = [line.get_label() for line in err_ax.get_lines()] + [c.get_label() for c in err_ax.collections]
    expected = 2 * 2 * math.sin(0.3 / 2)          # chord of the 0.3 rad lag on r = 2
    assert any(('e_mu %.2f m' % expected) == lab for lab in labels)


def test_plot_run_refuses_an_empty_csv(tmp_path):
    _, log = circle_log(n=3)
    csv = str(tmp_path / 'empty.csv')
    write_log(csv, log.select(np.zeros(3, dtype=bool)))
    with pytest.raises(ValueError):
        plots.plot_run(csv, str(tmp_path / 'x.png'))


def test_comparison_png(tmp_path):
    paths = []
    for i, lag in enumerate((0.1, 0.4)):
        _, log = circle_log(lag=lag)
        p = str(tmp_path / ('r%d.csv' % i))
        write_log(p, log)
        paths.append(('run %d' % i, p, 1.0 * i))
    png = plots.plot_comparison(paths, str(tmp_path / 'cmp.png'), title='cmp')
    with open(png, 'rb') as f:
        assert f.read(8) == PNG_MAGIC


def test_plot_of_a_reference_log(tmp_path):
    path = os.path.join(REFERENCE_LOGS, 'static_waypoint_yaw_180_mpc.csv')
    png = plots.plot_run(path, str(tmp_path / 'ref.png'), title='reference')
    assert os.path.getsize(png) < 150000


def _pixels_of(png, hex_colour, tol=0.06):
    """Number of pixels of the decoded PNG within ``tol`` (0..1 per channel) of ``hex_colour``."""
    from matplotlib import colors, image
    rgb = np.asarray(image.imread(png))[:, :, :3]
    target = np.array(colors.to_rgb(hex_colour))
    return int(np.sum(np.all(np.abs(rgb - target) < tol, axis=2)))


def test_the_png_shows_the_three_curves(tmp_path):
    """The saved picture, decoded: its size follows the figure and dpi, and the waypoint (red), estimate (blue)
    and ground-truth (green) colours are drawn; a log without ground truth has no green curve."""
    from matplotlib import image
    t, log = circle_log()
    csv = str(tmp_path / 'run.csv')
    write_log(csv, log)
    png = plots.plot_run(csv, str(tmp_path / 'run.png'), window=(2.0, 15.0))
    rgb = image.imread(png)
    fig = plots.run_figure(plots.load(csv))
    width, height = fig.get_size_inches() * plots.DEFAULT_DPI
    assert rgb.shape[:2] == (int(round(height)), int(round(width)))
    counts = dict((key, _pixels_of(png, colour)) for key, colour in plots.COLORS.items())
    assert all(n > 200 for n in counts.values()), counts
    assert np.mean(rgb[:, :, :3]) > 0.7            # mostly white paper, not a black or empty canvas
    _, no_truth = circle_log()
    for axis in 'xyz':
        no_truth.columns[axis + '_sphinx'][:] = np.nan
    csv2 = str(tmp_path / 'no_truth.csv')
    write_log(csv2, no_truth)
    png2 = plots.plot_run(csv2, str(tmp_path / 'no_truth.png'))
    assert _pixels_of(png2, plots.COLORS['truth']) < 0.1 * counts['truth']


def test_drawn_data_are_the_logs_columns():
    """The curves hold the CSV's numbers: x of the estimate, truth and waypoint against seconds since start,
    and the error curve is |waypoint - estimate| (here the chord of the 0.3 rad lag on r = 2)."""
    t, log = circle_log(lag=0.3)
    fig = plots.run_figure(log)
    x_ax = fig.axes[0]
    lines = dict((line.get_label(), line) for line in x_ax.get_lines())
    k = plots._decimate(len(t))
    assert np.allclose(lines['waypoint'].get_xdata(), log.t[::k])
    assert np.allclose(lines['waypoint'].get_ydata(), log.columns['wp_x'][::k])
    assert np.allclose(lines['drone (estimate)'].get_ydata(), log.columns['x_anafi'][::k])
    assert np.allclose(lines['ground truth'].get_ydata(), log.columns['x_sphinx'][::k])
    err = dict((line.get_label(), line) for line in fig.axes[-1].get_lines())
    assert np.allclose(err['vs estimate'].get_ydata(), 2 * 2 * math.sin(0.3 / 2), atol=1e-6)
    truth_error = np.linalg.norm(log.position('sphinx')[::k] - log.waypoint()[::k, :3], axis=1)
    assert np.allclose(err['vs ground truth'].get_ydata(), truth_error)


def test_comparison_overlays_each_run_against_its_own_offset():
    runs = []
    for i, lag in enumerate((0.1, 0.4)):
        _, log = circle_log(lag=lag)
        runs.append(('run %d' % i, log, 2.0 * i))
    fig = plots.comparison_figure(runs)
    x_ax = fig.axes[0]
    drawn = dict((line.get_label(), line) for line in x_ax.get_lines() if line.get_label().startswith('run'))
    assert sorted(drawn) == ['run 0', 'run 1']
    for label, log, offset in runs:
        k = plots._decimate(len(log.t))
        assert np.allclose(drawn[label].get_xdata(), log.t[::k] - offset)
        assert np.allclose(drawn[label].get_ydata(), log.columns['x_anafi'][::k])
    assert drawn['run 0'].get_color() != drawn['run 1'].get_color()

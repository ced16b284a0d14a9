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
    """The saved picture, decoded: its size follows the figure and dpi (cropped to what is drawn: the white margin
    goes, the legends outside the axes stay), and the waypoint (red), estimate (blue)
    and ground-truth (green) colours are drawn; a log without ground truth has no green curve."""
    from matplotlib import image
    t, log = circle_log()
    csv = str(tmp_path / 'run.csv')
    write_log(csv, log)
    png = plots.plot_run(csv, str(tmp_path / 'run.png'), window=(2.0, 15.0))
    rgb = image.imread(png)
    fig = plots.run_figure(plots.load(csv))
    width, height = fig.get_size_inches() * plots.DEFAULT_DPI
    assert 0.8 * height < rgb.shape[0] < 1.2 * height and 0.8 * width < rgb.shape[1] < 1.2 * width, rgb.shape
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


def takeoff_log(n=600, late=0.44):
    """A run that starts 5 m from its waypoint (the take-off) and tracks within ``late`` m from t = 5 s on."""
    t = np.arange(n) * 0.05
    wp = np.column_stack([np.zeros(n), np.zeros(n), np.full(n, 5.0)])
    gap = np.where(t < 5.0, 5.0 * (1.0 - t / 5.0), late * (0.5 + 0.5 * np.sin(t)))
    est = wp - np.column_stack([gap, np.zeros(n), np.zeros(n)])
    return t, make_log(t, est, wp)


def test_error_limits_come_from_the_measured_window():
    t = np.arange(100) * 0.1
    e = np.where(t < 2.0, 5.0, 0.4)
    x, y = plots.error_limits(t, [e, np.full(100, np.nan)], (3.0, 9.0))
    assert x == (3.0, 9.0) and y[0] == 0.0 and y[1] == pytest.approx(1.1 * 0.4)
    x, y = plots.error_limits(t, [e], None)                   # no window: the whole run
    assert x == (t[0], t[-1]) and y[1] == pytest.approx(5.5)
    _, y = plots.error_limits(t, [np.zeros(100)], (3.0, 9.0))  # a perfect run: not a 1e-16 m scale
    assert y == (0.0, plots.ERROR_MIN_SPAN)
    x, _ = plots.error_limits(t, [e], (50.0, 60.0))            # a window without samples: the whole run
    assert x == (t[0], t[-1])


def test_the_error_panel_shows_the_measured_window_not_the_take_off():
    t, log = takeoff_log()
    window = (6.0, float(t[-1]))
    fig = plots.run_figure(log, window=window)
    err_ax = fig.axes[-1]
    e = np.hypot(log.columns['wp_x'] - log.columns['x_anafi'], 0.0)
    inside = e[(t >= window[0]) & (t <= window[1])]
    assert err_ax.get_xlim() == pytest.approx(window)
    assert err_ax.get_ylim() == pytest.approx((0.0, 1.1 * inside.max()))
    assert err_ax.get_ylim()[1] < 1.0                          # the 5 m of the take-off do not set the scale


def test_legends_sit_outside_the_data():
    t, log = circle_log()
    fig = plots.run_figure(log, window=(2.0, 15.0), title='circle')
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    for ax in fig.axes:
        legend = ax.get_legend()
        if legend is not None:
            box, area = legend.get_window_extent(renderer), ax.get_window_extent(renderer)
            assert not box.overlaps(area), 'the legend of %r covers its axes' % ax.get_title()
    assert any(ax.get_legend() is not None for ax in fig.axes)


def test_a_failed_run_says_failed_in_its_title():
    _, log = circle_log()
    fig = plots.run_figure(log, title='circle_mpc', failed='no ground truth')
    assert fig._suptitle.get_text() == 'circle_mpc\nFAILED: no ground truth'
    assert plots.figure_title('circle_mpc', failed=True) == 'circle_mpc\nFAILED'
    assert plots.figure_title('circle_mpc') == 'circle_mpc'
    assert plots.figure_title('x', 'wind 3.0 m/s', failed='y' * 200).split('\n')[1].endswith('...')
    assert 'FAILED' not in plots.run_figure(log, title='circle_mpc')._suptitle.get_text()


@pytest.mark.parametrize('fmt', ['svg', 'pdf', 'png'])
def test_a_run_renders_as_svg_pdf_and_png(tmp_path, fmt):
    import xml.etree.ElementTree as ElementTree
    _, log = circle_log(n=120)
    csv = str(tmp_path / 'run.csv')
    write_log(csv, log)
    out = plots.plot_run(csv, str(tmp_path / ('run.' + fmt)), summary={'name': 'tiny', 'window': [1.0, 3.5]},
                         failed='not ready within 90 s', dpi=150)
    data = open(out, 'rb').read()
    if fmt == 'svg':
        root = ElementTree.fromstring(data)
        assert root.tag.endswith('svg')
        assert b'FAILED' in data      # the title (drawn as glyph paths, its text in a comment beside them)
    elif fmt == 'pdf':
        assert data.startswith(b'%PDF') and data.rstrip().endswith(b'%%EOF')
    else:
        assert data[:8] == PNG_MAGIC
    # no creation date: the same run gives the same file
    again = plots.plot_run(csv, str(tmp_path / ('again.' + fmt)), summary={'name': 'tiny', 'window': [1.0, 3.5]},
                           failed='not ready within 90 s', dpi=150)
    assert open(again, 'rb').read() == data


def test_the_format_comes_from_the_argument_or_the_extension():
    assert plots.figure_format('a/run.svg') == 'svg' and plots.figure_format('a/run.PDF') == 'pdf'
    assert plots.figure_format('a/run.png.tmp-12') == 'png'        # an unknown extension: the default
    assert plots.figure_format('a/run.tmp', 'pdf') == 'pdf'
    with pytest.raises(ValueError):
        plots.figure_format('a/run.png', 'jpg')
    assert plots.check_dpi('300') == 300.0
    for bad in ('0', 'x', float('nan'), 5000):
        with pytest.raises(ValueError):
            plots.check_dpi(bad)

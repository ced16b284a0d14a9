"""docs/calibration.md and the model YAMLs are their templates filled with the calibration's stored figures.

``make calibrate`` (anafi_lab/cli/calibrate_model.py) stores the figures in benchmarks/results/calibration.yaml
and renders docs/calibration.md, anafi_sim/config/anafi_model.yaml and anafi_model_fitted.yaml from them;
rendering them again gives the committed files byte for byte (without the fits, which take minutes), every
figure in them comes from the stored data, and the templates' words have no figure of their own.
"""
import copy
import os
import re

import yaml

from anafi_sim import paths
from anafi_lab.reports import conditions_report
from anafi_lab.reports import calibration_report as report

ROOT = paths.checkout()
REPORT = os.path.join(ROOT, 'docs', 'calibration.md')
STORED = os.path.join(ROOT, 'benchmarks', 'results', 'calibration.yaml')
TEMPLATES = os.path.join(ROOT, 'anafi_lab', 'reports', 'templates')


def stored_context(part='report'):
    with open(STORED) as stream:
        return yaml.safe_load(stream)[part]


def committed(path=REPORT):
    with open(path) as stream:
        return stream.read()


def test_report_renders_byte_identical_from_the_stored_figures():
    """The report is the template filled with the stored figures; its "Real flights" section is
    calibrate_conditions.py's (re-rendered from its own figures: test/unit/lab/test_conditions.py)."""
    text, doc = report.render_report(stored_context()), committed()
    kept = conditions_report.existing_section(doc)
    assert (conditions_report.replace_section(text, kept) if kept else text) == doc


def test_model_files_render_byte_identical_from_the_stored_figures():
    for part, name in (('model', 'anafi_model.yaml'), ('model_fitted', 'anafi_model_fitted.yaml')):
        path = os.path.join(ROOT, 'anafi_sim', 'config', name)
        assert report.render_model_yaml(stored_context(part)) == committed(path), name


def test_a_stored_figure_changes_the_report_where_it_is_quoted():
    context = stored_context()
    changed = copy.deepcopy(context)
    changed['drag']['rms'] = 12.3456
    changed['effects']['gyroscopic']['coupling'] = -9.876
    text = report.render_report(changed)
    assert text != committed()
    assert 'rms 12.3456 m/s^2, R^2' in text and 'G = -9.876 s' in text
    assert 'rms %.4f m/s^2, R^2' % context['drag']['rms'] in committed()


# Digits the template's words may hold: names (sections, tables, equations, logs, symbols), units, the 0 and 1
# of formulas and definitions, the YAML scalar's ".0" and the command `UPDATE=1 make calibrate`.
ALLOWED = re.compile(r"R\^2|\(c-e\)|Table [23]|eq\. \(?15\)?|issue 2|float16|3-D|1/k|1 / tau|1/\(2 rate\)|"
                     r"1 / \(c tau\)|1/\(c tau\)|\(I - G r J\)\^-1|1 / sqrt\(1 \+ \(G r\)\^2\)|"
                     r"\(1 \+ \(G r\)\^2\)\^\(-p/2\)|m/s\^2|1/s\^2|2 pi i v|k1|k2|b0|v0|v1|x_straight_4_pid|"
                     r"yaw-180|yaw-0|x_straight_2/3_pid|\^-1|2\^|1/|x_pred|\(1 - a r\)|0, 1\)|1 - its gain|"
                     r"time 0|b = 0|w > 0|of 1 |\(1 \+ c \|v\|\)| 1, as the model|\.0|\(1 - a\)|UPDATE=1 make")


# Labels the fidelity and batch templates' words may hold: names of logs and scenarios, of the paper's sections,
# tables and figures and of the static steps (yaw 0 / 180, WP0 / WP1), SO(3), float16 and the 16-bit wrap, the units
# 1/s and 1/k, the origin of log time, the 0 that starts a range ("0-<figure> ms") and the 1 of a ratio that changes
# nothing.
LABELS = re.compile(r"\b(?:x_straight|static_waypoint|straight|circle|vertical)_[\w/.]*|Tables? \d(?:-\d| and \d)?|"
                    r"Figs?\. \d(?: and \d)?|Sec\. V\.B|\byaw[- ]?(?:0|180)\b|180 deg step|WP[01]|SO\(3\)|16-bit|"
                    r"float16|1/[sk]\b|t = 0|log time 0|\b0-(?= )|\b1 when|not 1\b")
PLACEHOLDERS = re.compile(r'\{\{.*?\}\}|\{%.*?%\}|\{#.*?#\}', flags=re.S)


def typed_figures(name, allowed):
    """The lines of template ``name`` whose words (placeholders removed) hold a digit ``allowed`` does not take."""
    with open(os.path.join(TEMPLATES, name)) as stream:
        words = PLACEHOLDERS.sub(' ', stream.read())
    return [line.strip()[:200] for line in words.split('\n') if re.search(r'\d', allowed.sub(' ', line))]


def test_template_words_hold_no_figure():
    for name in sorted(os.listdir(TEMPLATES)):
        if name.startswith(('calibration', 'anafi_model')):
            assert typed_figures(name, ALLOWED) == [], '%s: a figure typed into the words' % name


def test_fidelity_and_batch_template_words_hold_no_figure():
    names = ['fidelity.md', 'batch.md'] + sorted(os.path.join('fidelity', n)
                                                 for n in os.listdir(os.path.join(TEMPLATES, 'fidelity')))
    for name in names:
        assert typed_figures(name, LABELS) == [], '%s: a figure typed into the words' % name


def test_the_allowed_words_do_not_hide_a_figure():
    for typed in ('rms 0.35 rad', 'at 20 Hz', '~94 % of the command', 'k2 ~ 0.07 1/s^2', 'R 84.7 deg/s'):
        assert re.search(r'\d', ALLOWED.sub(' ', typed)), typed
    for typed in ('lag 0.262 s', 'within +-10 %', '1.4-4.0x Sphinx\'s', 'yaw 8 / 18 / 40 deg', 'Table 3 is 10 / 10',
                  'x_straight_5_mpc 0.81 -> 0.97', '(0.99 unrounded', '15 s settle', 'the paper: 2.59',
                  '--workers 2', '(0-20 ms)', 'up to 19 cm'):
        assert re.search(r'\d', LABELS.sub(' ', typed)), typed


# Labels of the real-flight sections' words besides LABELS: their enumeration (1)-(5), the formula's sqrt(6), and
# the gains K = 0 (no wind handling) and K = 1 (full cancellation), the time constant tau = 0 (instantaneous).
CONDITIONS_LABELS = re.compile(LABELS.pattern + r"|\([1-5]\)|sqrt\(6\)|K = [01]\b|tau = 0\b|m/s\^2")


def test_the_real_flight_templates_hold_no_figure():
    names = sorted(os.path.join('conditions', n) for n in os.listdir(os.path.join(TEMPLATES, 'conditions')))
    assert names
    for name in names:
        assert typed_figures(name, CONDITIONS_LABELS) == [], '%s: a figure typed into the words' % name
    assert re.search(r'\d', CONDITIONS_LABELS.sub(' ', 'capped at 10 deg')), 'the labels hide a figure'

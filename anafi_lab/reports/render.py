"""Reports from templates: Markdown templates (anafi_lab/reports/templates/*.md, Jinja2) filled with computed figures.

A report is a template plus a context of figures: no figure is typed into the prose and no prose is built by
string concatenation in Python. ``render(name, **context)`` fills ``templates/<name>``; the filters every template
has are ``fmt`` (``anafi_sim.numeric.fmt``: digits, '-' when missing), ``pct`` (a ratio as a signed percent),
``paragraph`` (``{% filter paragraph %}``: a paragraph wrapped in the template as one line of the report) and
Jinja2's own; ``table(header, rows)`` draws a Markdown table.
"""
import functools
import re

import jinja2

from anafi_sim.numeric import fmt


def pct(ratio, digits=0):
    """A ratio as a signed percent change: 1.07 -> '+7 %', 0.9 -> '-10 %' ('-' when missing)."""
    text = fmt(None if ratio is None else 100.0 * (ratio - 1.0), digits)
    if text == '-':
        return text
    return ('%s %%' % text) if text.startswith('-') else ('+%s %%' % text)


def na(value, digits=3):
    """``fmt`` with 'n/a' for a missing value."""
    return fmt(value, digits, missing='n/a')


def markdown_table(header, rows):
    """Markdown lines of a table: header, separator, one line per row (cells as they are, ``str`` of each)."""
    return ['| ' + ' | '.join(str(c) for c in header) + ' |', '|' + '---|' * len(header)] + \
        ['| ' + ' | '.join(str(c) for c in row) + ' |' for row in rows]


def table(header, rows):
    """A Markdown table as one text (no trailing newline): the templates' ``table(header, rows)``."""
    return '\n'.join(markdown_table(header, rows))


def paragraph(text):
    """A paragraph wrapped over several lines of a template as one line (every run of white space one space),
    followed by a line break."""
    return re.sub(r'\s+', ' ', text.strip()) + '\n'


@functools.lru_cache(maxsize=None)
def environment():
    """The Jinja2 environment of the report templates (found through the package: devel and install spaces)."""
    env = jinja2.Environment(loader=jinja2.PackageLoader('anafi_lab.reports', 'templates'),
                             undefined=jinja2.StrictUndefined, trim_blocks=True, lstrip_blocks=True,
                             keep_trailing_newline=True, autoescape=False)
    env.filters['fmt'] = fmt
    env.filters['pct'] = pct
    env.filters['na'] = na
    env.globals['table'] = table
    env.filters['paragraph'] = paragraph
    return env


def render(name, **context):
    """The text of template ``name`` (e.g. 'calibration.md') filled with ``context``."""
    return environment().get_template(name).render(**context)

"""Summary statistics of a series and numbers as text: the one place for both (pure Python).

Used by the mission's cores (evaluation, monitor), the lab (runs, sweeps, reports) and the benchmarks, so that a
mean, a standard deviation, a median or a table cell is computed and written the same way everywhere (numpy arrays:
``np.std`` is ddof 0 too). One convention for a spread: ``std`` is the population standard deviation (ddof 0) unless
a table says it is the spread of a sample (``summary_stats(values, sample=True)``, ddof 1).

Numbers from text (``parse_number``, ``parse_integer``): the one parser of the launch check
(anafi_sim/launch_check.py) and the nodes' parameters (anafi_sim/ros/params.py), so both accept the same
values (``1e0``, ``-2.5``; ASCII digits only, finite) and both hold them to the same ``PARAMETER_RANGES``.
"""
import collections
import math
import re
import statistics

_DECIMAL = re.compile(r'^[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?$')
_INTEGER = re.compile(r'^[+-]?[0-9]+$')

#: name -> (minimum, maximum): the physical range of a launch argument / node parameter of that name
#: (the launch check and the nodes refuse a value outside it)
PARAMETER_RANGES = {
    'rtf': (0.0, 1000.0),              # real-time factor
    'initial_x': (-10000.0, 10000.0),  # m, take-off point
    'initial_y': (-10000.0, 10000.0),  # m
    'initial_yaw': (-1000.0, 1000.0),  # rad
    'plot_dpi': (10.0, 1200.0),        # dots per inch of a run's figure
}


def parse_number(value):
    """A finite float from a number (not a bool) or its text (decimal, ASCII digits, optional exponent);
    None otherwise."""
    if isinstance(value, bool):
        return None
    if isinstance(value, (int, float)):
        out = float(value) if not isinstance(value, int) or abs(value) < 1e308 else float('inf')
    elif isinstance(value, str) and _DECIMAL.match(value.strip()):
        out = float(value.strip())
    else:
        return None
    return out if math.isfinite(out) else None


def parse_integer(value):
    """An int from an int (not a bool) or its text (ASCII digits, optional sign); None otherwise."""
    if isinstance(value, bool):
        return None
    if isinstance(value, int):
        return value
    if isinstance(value, str) and _INTEGER.match(value.strip()):
        return int(value.strip())
    return None


def range_problem(name, value):
    """None when the number ``value`` lies in ``PARAMETER_RANGES[name]`` (or there is no range), else what
    is wrong."""
    bounds = PARAMETER_RANGES.get(name)
    if bounds is None or bounds[0] <= value <= bounds[1]:
        return None
    return 'must lie in [%g, %g], got %g' % (bounds[0], bounds[1], value)


def finite(values):
    """The finite values of ``values`` as floats (None, NaN, inf and non-numbers left out)."""
    out = []
    for v in values:
        if v is None or isinstance(v, bool):
            continue
        try:
            v = float(v)
        except (TypeError, ValueError):
            continue
        if math.isfinite(v):
            out.append(v)
    return out


def summary_stats(values, sample=False):
    """{'n', 'mean', 'std', 'min', 'max'} of the finite values (an OrderedDict), or None when there are none.

    ``std`` is the population standard deviation (ddof 0: the spread of the values themselves, as the runs'
    e_sigma), or with ``sample`` the sample one (ddof 1, 0.0 for one value: the spread of a population of which
    the values are a sample, as the seeds of a predicted cell). The sums run left to right in plain floats (not
    ``statistics.fmean`` / ``pstdev``, whose exact sums move the last bits of the published figures)."""
    v = finite(values)
    if not v:
        return None
    mean = sum(v) / len(v)
    squares = sum((x - mean) ** 2 for x in v)
    if sample:
        std = math.sqrt(squares / (len(v) - 1)) if len(v) > 1 else 0.0
    else:
        std = math.sqrt(squares / len(v))
    return collections.OrderedDict([('n', len(v)), ('mean', mean), ('std', std), ('min', min(v)), ('max', max(v))])


def median(values):
    """The median of the finite values (the mean of the two middle ones for an even count); None when empty."""
    v = finite(values)
    return statistics.median(v) if v else None


def fmt(value, digits=2, missing='-'):
    """A number as text with ``digits`` decimals; ``missing`` for None, booleans, NaN, inf and non-numbers."""
    if value is None or isinstance(value, bool):
        return missing
    try:
        v = float(value)
    except (TypeError, ValueError):
        return missing
    if not math.isfinite(v):
        return missing
    return '%.*f' % (digits, v)

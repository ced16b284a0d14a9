"""Summary statistics of a series and numbers as text: the one place for both (pure Python).

Used by the mission's cores (evaluation, monitor), the lab (runs, sweeps, reports) and the benchmarks, so that a
mean, a standard deviation or a table cell is computed and written the same way everywhere.
"""
import collections
import math


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


def summary_stats(values):
    """{'n', 'mean', 'std' (population), 'min', 'max'} of the finite values (an OrderedDict), or None when
    there are none."""
    v = finite(values)
    if not v:
        return None
    mean = sum(v) / len(v)
    std = math.sqrt(sum((x - mean) ** 2 for x in v) / len(v))
    return collections.OrderedDict([('n', len(v)), ('mean', mean), ('std', std), ('min', min(v)), ('max', max(v))])


def median(values):
    """The median of the finite values (the mean of the two middle ones for an even count); None when empty."""
    v = sorted(finite(values))
    if not v:
        return None
    mid = len(v) // 2
    return v[mid] if len(v) % 2 else 0.5 * (v[mid - 1] + v[mid])


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

"""What a live tuning request changed (pure, no ROS): the record of one dynamic_reconfigure request.

A request names values for some parameters; the server clamps each to its range (cfg/*.cfg min / max) and the
controller may refuse or adjust them. ``changes`` compares the configuration before, the values asked for and
the configuration applied, and returns one record per parameter that was asked for with a different value
or that changed: ``{'parameter', 'old', 'new', 'requested', 'outcome'}`` with outcome

- ``applied``: new == requested;
- ``clamped``: requested was outside [min, max] and new is the bound;
- ``refused``: new differs from requested for another reason (the controller kept or adjusted the value).

``describe`` turns a record into one log line. Nodes wire it in ``anafi_sim/ros/reconfigure.py``.
"""

OUTCOMES = ('applied', 'clamped', 'refused')


def _same(a, b):
    if isinstance(a, float) or isinstance(b, float):
        try:
            return float(a) == float(b)
        except (TypeError, ValueError):
            return False
    return a == b


def changes(before, requested, applied, names, minimum=None, maximum=None):
    """Records of the parameters ``names`` (in that order) that the request touched: asked for with a value
    other than ``before``'s, or changed in ``applied``. ``minimum`` / ``maximum``: {name: bound} of the
    server (a value at a bound it was clamped to counts as ``clamped``)."""
    minimum, maximum = minimum or {}, maximum or {}
    out = []
    for name in names:
        if name not in requested and name not in applied:
            continue
        old = before.get(name)
        want = requested.get(name, old)
        new = applied.get(name, old)
        if _same(want, old) and _same(new, old):
            continue
        if _same(new, want):
            outcome = 'applied'
        elif (name in minimum and want is not None and _less(want, minimum[name]) and _same(new, minimum[name])) \
                or (name in maximum and want is not None and _less(maximum[name], want)
                    and _same(new, maximum[name])):
            outcome = 'clamped'
        else:
            outcome = 'refused'
        out.append({'parameter': name, 'old': old, 'new': new, 'requested': want, 'outcome': outcome})
    return out


def _less(a, b):
    try:
        return a < b
    except TypeError:
        return False


def describe(record, minimum=None, maximum=None):
    """One line: 'r: 0.1 -> 0.5' / 'r: requested -3 is outside [0, 10]: clamped to 0 (was 0.1)' / ..."""
    name, old, new, want = record['parameter'], record['old'], record['new'], record['requested']
    if record['outcome'] == 'applied':
        return '%s: %s -> %s' % (name, old, new)
    if record['outcome'] == 'clamped':
        lo = (minimum or {}).get(name)
        hi = (maximum or {}).get(name)
        return '%s: requested %s is outside [%s, %s]: clamped to %s (was %s)' % (name, want, lo, hi, new, old)
    return '%s: requested %s not applied: %s (was %s)' % (name, want, new, old)

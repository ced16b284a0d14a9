"""Checked reading of node parameters (pure: the node passes its parameter getter).

Every node reads its ``~params`` through a ``ParamReader``:

    p = ParamReader(lambda name, default: rospy.get_param('~' + name, default))
    rate = p.number('rate', 100.0, minimum=0.0, strict=True)

A bad value raises ``ParamError`` (a ValueError) whose message names the
parameter, what it must be and what it got; nodes turn it into a fatal log
line and a non-zero exit at start-up.
"""
import math
import re

from anafi_sim.numeric import parse_integer, parse_number, range_problem

_BASE_NAME = re.compile(r'^[A-Za-z][A-Za-z0-9_]*$')


class ParamError(ValueError):
    """A parameter has a value the node cannot run with."""


def _is_number(value):
    return not isinstance(value, bool) and isinstance(value, (int, float)) and math.isfinite(value)


class ParamReader(object):
    """Typed, range-checked parameter access; ``getter(name, default)`` returns the raw value."""

    def __init__(self, getter):
        self._get = getter

    def number(self, name, default, minimum=None, maximum=None, strict=False):
        """A finite float (a number or its text, ``anafi_sim.numeric.parse_number``: the launch check's parser);
        ``minimum``/``maximum`` bound it (exclusive when ``strict``), and so does the physical range of a
        parameter of that name (``anafi_sim.numeric.PARAMETER_RANGES``)."""
        raw = self._get(name, default)
        value = parse_number(raw)
        ok = value is not None
        if ok and range_problem(name, value):
            raise ParamError('~%s %s' % (name, range_problem(name, value)))
        if ok and minimum is not None:
            ok = value > minimum if strict else value >= minimum
        if ok and maximum is not None:
            ok = value < maximum if strict else value <= maximum
        if not ok:
            bounds = []
            if minimum is not None:
                bounds.append('%s %g' % ('>' if strict else '>=', minimum))
            if maximum is not None:
                bounds.append('%s %g' % ('<' if strict else '<=', maximum))
            raise ParamError('~%s must be a finite number%s, got %s'
                             % (name, (' ' + ' and '.join(bounds)) if bounds else '', repr(raw)[:100]))
        return float(value)

    def positive(self, name, default):
        """A finite number > 0."""
        return self.number(name, default, minimum=0.0, strict=True)

    def integer(self, name, default, minimum=None, maximum=None):
        """An int (not a bool), optionally >= ``minimum`` and <= ``maximum``."""
        raw = self._get(name, default)
        value = parse_integer(raw)
        if value is None or (minimum is not None and value < minimum) or (maximum is not None and value > maximum):
            bounds = []
            if minimum is not None:
                bounds.append('>= %d' % minimum)
            if maximum is not None:
                bounds.append('<= %d' % maximum)
            raise ParamError('~%s must be an integer%s, got %s'
                             % (name, (' ' + ' and '.join(bounds)) if bounds else '', repr(raw)[:100]))
        return value

    def flag(self, name, default):
        """true or false (no strings, no numbers)."""
        value = self._get(name, default)
        if not isinstance(value, bool):
            raise ParamError('~%s must be true or false, got %r' % (name, value))
        return value

    def string(self, name, default, allow_empty=True):
        """A string, stripped of surrounding white space."""
        value = self._get(name, default)
        if not isinstance(value, str) or (not allow_empty and not value.strip()):
            raise ParamError('~%s must be a %sstring, got %r' % (name, '' if allow_empty else 'non-empty ', value))
        return value.strip()

    def text(self, name, default=''):
        """Free text (a label): a string, or a number taken as its text (roslaunch types value="7" as an int);
        an unset (None) value is ''."""
        value = self._get(name, default)
        if value is None:
            return ''
        if not isinstance(value, str) and not _is_number(value):
            raise ParamError('~%s must be a text, got %r' % (name, value))
        return str(value).strip()

    def ros_name(self, name, default):
        """A non-empty ROS name without white space (a trailing '/' is dropped)."""
        value = self._get(name, default)
        if not isinstance(value, str) or not value.strip() or any(c.isspace() for c in value):
            raise ParamError('~%s must be a non-empty ROS name, got %r' % (name, value))
        return value.rstrip('/') or '/'

    def base_name(self, name, default):
        """A ROS base name: a letter, then letters, digits and '_' (e.g. a drone name)."""
        value = self._get(name, default)
        if not isinstance(value, str) or not _BASE_NAME.match(value):
            raise ParamError('~%s must be a ROS base name (a letter, then letters, digits, _), got %r'
                             % (name, value))
        return value

    def word(self, name, default, forbidden=''):
        """A string without white space and without the characters of ``forbidden`` (may be empty)."""
        value = self._get(name, default)
        if not isinstance(value, str) or any(c.isspace() or c in forbidden for c in value):
            raise ParamError('~%s must be a string without spaces%s, got %r'
                             % (name, ''.join(' or %r' % c for c in forbidden), value))
        return value

    def names(self, name, default):
        """A list of names (strings); a string is split at commas and white space."""
        value = self._get(name, default)
        if isinstance(value, str):
            value = [v for v in value.replace(',', ' ').split() if v]
        if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) for v in value):
            raise ParamError('~%s must be a list of names, got %r' % (name, value))
        return list(value)

    def command(self, name, default):
        """A command line: a non-empty string, or a non-empty list of arguments (strings or numbers)."""
        value = self._get(name, default)
        if isinstance(value, str) and value.strip():
            return value
        if isinstance(value, list) and value and all(
                isinstance(a, str) or _is_number(a) for a in value):
            return value
        raise ParamError('~%s must be a non-empty command string or list of arguments, got %r' % (name, value))

    def mapping(self, name, default=None):
        """A dict (a YAML mapping loaded into ~name), or ``default`` (None) when unset."""
        value = self._get(name, default)
        if value is not default and not isinstance(value, dict):
            raise ParamError('~%s must be a mapping (YAML dict), got %r' % (name, value))
        return value

    def vector(self, name, default, length):
        """A list of ``length`` finite numbers, as a tuple of floats."""
        value = self._get(name, default)
        if not isinstance(value, (list, tuple)) or len(value) != length or not all(_is_number(v) for v in value):
            raise ParamError('~%s must be a list of %d finite numbers, got %r' % (name, length, value))
        return tuple(float(v) for v in value)

    def choice(self, name, default, choices):
        """One of ``choices`` (strings)."""
        value = self._get(name, default)
        if value not in choices:
            raise ParamError('~%s must be one of %s, got %r' % (name, ', '.join(choices), value))
        return value

"""anafi_sim.ros.params: checked parameter reading (every bad value refused with the name in the message)."""
import math

import pytest

from anafi_sim.ros.params import ParamError, ParamReader


def reader(**values):
    return ParamReader(lambda name, default: values.get(name, default))


def test_defaults_and_values():
    p = reader(rate=50)
    assert p.number('rate', 100.0) == 50.0 and isinstance(p.number('rate', 1), float)
    assert p.number('missing', 2.5) == 2.5
    assert p.flag('on', True) is True
    assert p.string('cmd', ' tlm ') == 'tlm'
    assert p.vector('offset', [0.1, 0, 0], 3) == (0.1, 0.0, 0.0)
    assert p.integer('seed', 3, minimum=0) == 3
    assert p.ros_name('ns', '/gazebo/') == '/gazebo'
    assert p.choice('mode', 'single', ('single', 'distributed')) == 'single'


@pytest.mark.parametrize('value', [float('nan'), float('inf'), 'fast', True, None, [1]])
def test_non_numbers_refused(value):
    with pytest.raises(ParamError, match='~rate'):
        reader(rate=value).number('rate', 1.0)


def test_bounds_inclusive_and_strict():
    assert reader(x=0.0).number('x', 1.0, minimum=0.0) == 0.0
    with pytest.raises(ParamError, match='> 0'):
        reader(x=0.0).positive('x', 1.0)
    with pytest.raises(ParamError, match='<= 1'):
        reader(x=1.5).number('x', 0.0, maximum=1.0)
    assert reader(x=200).number('x', 0.0, minimum=200) == 200.0
    with pytest.raises(ParamError, match='>= 200'):
        reader(x=199.9).number('x', 0.0, minimum=200)


@pytest.mark.parametrize('method,args,value', [
    ('flag', (True,), 'true'), ('flag', (True,), 1),
    ('integer', (0,), 1.5), ('integer', (0,), True), ('integer', (0, 0), -1),
    ('string', ('',), 3), ('string', ('x', False), '  '),
    ('ros_name', ('a',), 'has space'), ('ros_name', ('a',), ''),
    ('vector', ([0, 0, 0], 3), [0, 0]), ('vector', ([0, 0, 0], 3), [0, math.nan, 0]),
    ('choice', ('a', ('a', 'b')), 'c'),
])
def test_bad_values_refused(method, args, value):
    with pytest.raises(ParamError, match='~p '):
        getattr(reader(p=value), method)('p', *args)


def test_integer_range_inclusive():
    assert reader(port=0).integer('port', 9060, minimum=0, maximum=65535) == 0
    assert reader(port=65535).integer('port', 9060, minimum=0, maximum=65535) == 65535
    with pytest.raises(ParamError, match='~port must be an integer >= 0 and <= 65535'):
        reader(port=65536).integer('port', 9060, minimum=0, maximum=65535)
    with pytest.raises(ParamError, match='<= 10'):
        reader(n=11).integer('n', 0, maximum=10)


def test_names_lists_and_separated_strings():
    assert reader(n=['a', 'b']).names('n', []) == ['a', 'b']
    assert reader(n='evaluator recorder,  x').names('n', []) == ['evaluator', 'recorder', 'x']
    assert reader().names('n', []) == []
    for bad in ([1, 'a'], 3, None):
        with pytest.raises(ParamError, match='~n must be a list of names'):
            reader(n=bad).names('n', [])


def test_command_string_or_argument_list():
    assert reader(c='tlm-data-logger -r 0').command('c', 'x') == 'tlm-data-logger -r 0'
    assert reader(c=['tlm', '-r', 0]).command('c', 'x') == ['tlm', '-r', 0]
    for bad in ('  ', [], ['a', None], ['a', True], 7):
        with pytest.raises(ParamError, match='~c must be a non-empty command'):
            reader(c=bad).command('c', 'x')


def test_base_name_word_and_text():
    assert reader(d='anafi_2').base_name('d', 'anafi') == 'anafi_2'
    for bad in ('2anafi', 'a/b', 'a b', '', 3):
        with pytest.raises(ParamError, match='~d must be a ROS base name'):
            reader(d=bad).base_name('d', 'anafi')
    assert reader(w='').word('w', 'x', forbidden=':') == ''
    assert reader(w='sphinx.').word('w', 'x', forbidden=':') == 'sphinx.'
    for bad in ('a b', 'a:b', 3):
        with pytest.raises(ParamError, match="~w must be a string without spaces or ':'"):
            reader(w=bad).word('w', 'x', forbidden=':')
    assert reader(t=7).text('t') == '7' and reader(t=None).text('t') == '' and reader().text('t', ' x ') == 'x'
    with pytest.raises(ParamError, match='~t must be a text'):
        reader(t=[1]).text('t')


def test_mapping():
    assert reader(m={'gravity': 9.81}).mapping('m') == {'gravity': 9.81}
    assert reader().mapping('m') is None
    with pytest.raises(ParamError, match='~m must be a mapping'):
        reader(m=[1]).mapping('m')

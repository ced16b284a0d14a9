"""A fleet file is untrusted: any fleet file is refused with one line or yields a launch file that parses as XML
and holds no ``$(`` anywhere (roslaunch would substitute it), its comments closed only where they should be."""
import xml.etree.ElementTree as ET

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from anafi_sim.mission import fleet as fl

HOSTILE = ['$(eval exec("import os; os.system(\'touch pwned\')", dict()))', '$(env HOME)', '-->', '<x/>', '&amp;',
           '"', "'", 'a\nb', '../../etc/passwd', '/etc/passwd', 'circle_r2_v1', 'anafi1', 'airship', '$ (arg x)',
           'tlm-data-logger -r 0 inet:127.0.0.1:9060', 'tlm-data-logger inet:$(env HOST):1', '\x00', 'é']
TEXT = st.one_of(st.sampled_from(HOSTILE), st.text(max_size=40))
VALUE = st.one_of(TEXT, st.integers(-5, 70000), st.floats(allow_nan=True), st.none(),
                  st.lists(st.floats(-10, 10), max_size=4))


@st.composite
def fleet_files(draw):
    drones = []
    for i in range(draw(st.integers(1, 3))):
        d = {'name': draw(st.one_of(st.just('anafi%d' % (i + 1)), TEXT))}
        kind = draw(st.sampled_from(['scenario', 'waypoint', 'target']))
        if kind == 'scenario':
            d['scenario'] = draw(st.one_of(st.just('static_wp0'), TEXT))
        elif kind == 'waypoint':
            d['waypoint'] = draw(st.one_of(st.just([1, 2, 3]), VALUE))
        else:
            d['target'] = {'model': draw(st.one_of(st.just('airship'), TEXT))}
            if draw(st.booleans()):
                d['target']['offset_frame'] = draw(TEXT)
        for key in ('source', 'controller', 'telemetry_command', 'telemetry_port'):
            if draw(st.booleans()):
                d[key] = draw(VALUE)
        d['start'] = [6.0 * i, 0.0]
        drones.append(d)
    data = {'drones': drones}
    for key in ('name', 'description', 'layout'):
        if draw(st.booleans()):
            data[key] = draw(VALUE)
    return data


def _launch(fleet):
    ports = dict((d.name, 9100 + i) for i, d in enumerate(fleet.drones))
    files = dict((d.name, '/run/fleet/%s.scenario.yaml' % d.name) for d in fleet.drones if d.target is None)
    return fl.launch_xml(fleet, ports, files, '/run/fleet', source='/run/fleet/x.yaml')


def _values(element):
    for node in element.iter():
        for value in node.attrib.values():
            yield value
        yield node.text or ''


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(fleet_files())
def test_any_fleet_file_is_refused_in_one_line_or_gives_an_inert_launch_file(data):
    try:
        fleet = fl.fleet_from_dict(data, 'hostile')
        xml = _launch(fleet)
    except ValueError as error:
        assert '\n' not in str(error) and len(str(error)) < 2000
        return
    root = ET.fromstring(xml.split('\n', 1)[1])
    for value in _values(root):
        assert '$(' not in value.replace('$(find anafi_sim)/anafi_sim/launch/', '')


@pytest.mark.parametrize('drone, refused', [
    ({'name': 'a', 'target': {'model': HOSTILE[0]}}, 'target.model'),
    ({'name': 'a', 'scenario': '$(env HOME)'}, 'scenario must be the name'),
    ({'name': 'a', 'scenario': '/etc/passwd'}, 'scenario must be the name'),
    ({'name': 'a', 'scenario': '../../etc/passwd'}, 'scenario must be the name'),
    ({'name': 'a', 'scenario': 'x', 'source': 'sphinx', 'telemetry_command': 'tlm-data-logger inet:$(env H):1'},
     'without $'),
])
def test_the_repro_fields_are_refused(drone, refused):
    with pytest.raises(ValueError, match=refused.replace('$', r'\$').replace('.', r'\.')):
        fl.fleet_from_dict({'drones': [drone]}, 'hostile')


def test_comments_are_escaped():
    assert '--' not in fl.comment_text('a --> b -- c -')
    assert not fl.comment_text('x-').endswith('-')
    with pytest.raises(ValueError, match='substitute'):
        fl._arg('x', '$(eval 1)')

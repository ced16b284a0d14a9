"""Every launch argument a user can set is documented for ``roslaunch anafi_sim FILE --ros-args``.

roslaunch lists an <arg> with a default (optional) or with neither default nor value (required) and prints its
``doc=`` text, else "undocumented"; an <arg value=...> is a constant of the file (not listed when the value is
not empty) and an <arg> inside <include> passes a value on: neither needs a doc.
"""
import glob
import os
import xml.etree.ElementTree as ElementTree

import pytest

from conftest import ROOT

LAUNCH_FILES = sorted(glob.glob(os.path.join(ROOT, 'anafi_sim', 'launch', '*.launch')))


def settable_args(path):
    """(name, element) of every <arg> of the launch file at ``path`` a user sets: not inside an <include>,
    without value=."""
    out = []

    def walk(element):
        for child in element:
            if child.tag == 'arg' and child.get('value') is None:
                out.append((child.get('name'), child))
            elif child.tag != 'include':
                walk(child)
    walk(ElementTree.parse(path).getroot())
    return out


def test_there_are_launch_files():
    assert len(LAUNCH_FILES) >= 10


@pytest.mark.parametrize('path', LAUNCH_FILES, ids=os.path.basename)
def test_every_settable_argument_has_a_doc(path):
    undocumented = [name for name, arg in settable_args(path) if not (arg.get('doc') or '').strip()]
    assert undocumented == [], '%s: <arg> without doc=: %s' % (os.path.basename(path), ', '.join(undocumented))


@pytest.mark.parametrize('path', LAUNCH_FILES, ids=os.path.basename)
def test_an_empty_default_says_what_empty_means(path):
    """roslaunch lists an empty default as a required argument: its doc says it is optional (what empty does)."""
    unclear = [name for name, arg in settable_args(path)
               if arg.get('default') == '' and 'empty' not in arg.get('doc', '')]
    assert unclear == [], os.path.basename(path)


@pytest.mark.parametrize('path', LAUNCH_FILES, ids=os.path.basename)
def test_a_required_argument_says_so(path):
    required = [name for name, arg in settable_args(path)
                if arg.get('default') is None and not arg.get('doc', '').startswith('REQUIRED')]
    assert required == [], os.path.basename(path)


@pytest.mark.parametrize('path', LAUNCH_FILES, ids=os.path.basename)
def test_a_doc_has_no_substitution(path):
    """roslaunch resolves $(...) in doc= too: a doc that names one would be replaced (or fail)."""
    assert [name for name, arg in settable_args(path) if '$(' in arg.get('doc', '')] == []

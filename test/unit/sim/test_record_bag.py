"""anafi_sim/scripts/record_bag.py: the bag path it creates the directory for, and its refusal without -O."""
import importlib.util
import os
from conftest import ROOT


def load():
    spec = importlib.util.spec_from_file_location('record_bag', os.path.join(ROOT, 'anafi_sim', 'scripts',
                                                                             'record_bag.py'))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_output_path_forms():
    rb = load()
    assert rb.output_path(['-O', '/a/b.bag', '/t']) == '/a/b.bag'
    assert rb.output_path(['/t', '--output-name=/c/d.bag']) == '/c/d.bag'
    assert rb.output_path(['/t', '-O']) is None
    assert rb.output_path(['/t', '__name:=recorder']) is None


def test_without_output_it_refuses(capsys):
    assert load().main(['/topic']) == 2
    assert '-O' in capsys.readouterr().err

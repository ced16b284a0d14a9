"""anafi_sim/nodes/record_bag.py (rosrun anafi_sim record_bag.py): the bag path it creates the directory for, and its refusal without -O."""
from anafi_sim.nodes import record_bag


def load():
    return record_bag


def test_output_path_forms():
    rb = load()
    assert rb.output_path(['-O', '/a/b.bag', '/t']) == '/a/b.bag'
    assert rb.output_path(['/t', '--output-name=/c/d.bag']) == '/c/d.bag'
    assert rb.output_path(['/t', '-O']) is None
    assert rb.output_path(['/t', '__name:=recorder']) is None


def test_without_output_it_refuses(capsys):
    assert load().main(['/topic']) == 2
    assert '-O' in capsys.readouterr().err

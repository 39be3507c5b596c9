"""test/conftest.py's QUIET and LONGEST_FIRST name files and tests that exist."""

import ast
import os

HERE = os.path.dirname(os.path.abspath(__file__))


def _module(where):
    with open(os.path.join(HERE, where)) as f:
        return ast.parse(f.read())


def _conftest_value(name):
    """Return the literal assigned to `name` in conftest.py (read, not imported)."""
    for node in _module('conftest.py').body:
        if isinstance(node, ast.Assign) and [t.id for t in node.targets] == [name]:
            return ast.literal_eval(node.value)
    raise AssertionError('conftest.py assigns no %s' % name)


def test_every_quiet_test_exists():
    """A renamed test would leave the quiet pass silently, to be timed beside another."""
    for where, names in _conftest_value('QUIET').items():
        assert os.path.isfile(os.path.join(HERE, where)), where
        defined = {node.name for node in _module(where).body
                   if isinstance(node, ast.FunctionDef)}
        assert not set(names) - defined, (where, set(names) - defined)


def test_every_longest_first_file_exists():
    for where in _conftest_value('LONGEST_FIRST'):
        assert os.path.isfile(os.path.join(HERE, where)), where

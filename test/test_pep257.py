"""ament_pep257 (docstring conventions) over hair_sim/, test/ and tools/."""

import os

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.mark.linter
@pytest.mark.pep257
def test_pep257():
    """No pep257 finding in the Python sources."""
    from ament_pep257.main import main

    rc = main(argv=[os.path.join(ROOT, d) for d in ('hair_sim', 'test', 'tools')])
    assert rc == 0, 'Found code style errors / warnings'

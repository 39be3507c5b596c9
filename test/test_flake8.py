"""ament_flake8 over hair_sim/, test/ and tools/ (99 columns, the ROS 2 configuration)."""

import os

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.mark.flake8
@pytest.mark.linter
def test_flake8():
    """No flake8 finding in the Python sources."""
    from ament_flake8.main import main_with_errors

    paths = [os.path.join(ROOT, d) for d in ('hair_sim', 'test', 'tools', 'setup.py')]
    rc, errors = main_with_errors(argv=paths)
    assert rc == 0, 'Found %d code style errors / warnings:\n' % len(errors) + '\n'.join(errors)

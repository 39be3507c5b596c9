"""The shipped parameter file holds every node parameter, at its default, and says what it is."""

import os

import yaml

from hair_sim import paths
from hair_sim.ros.params import all_parameters


def _flat(tree, prefix=''):
    for key, value in tree.items():
        if isinstance(value, dict):
            yield from _flat(value, prefix + key + '.')
        else:
            yield prefix + key, value


def test_the_shipped_parameter_file_has_every_parameter_at_its_default():
    """
    config/hair_sim.yaml sets every declared parameter to its declared default and type.

    The README and --help send users to this file for every tunable; nine were missing
    from it (physics.model among them). A type that differs (0 for 0.0) would make rcl
    refuse the whole file at start.
    """
    with open(os.path.join(paths.config_dir(), 'hair_sim.yaml')) as f:
        shipped = dict(_flat(yaml.safe_load(f)['/**']['ros__parameters']))
    declared = all_parameters()
    assert set(shipped) == set(declared), set(shipped) ^ set(declared)
    for name, (default, _, _) in declared.items():
        assert type(shipped[name]) is type(default) and shipped[name] == default, \
            (name, shipped[name], default)


def test_every_parameter_says_what_it_is():
    """Each descriptor's description is a sentence, not the field's own name."""
    for name, (_, description, _) in all_parameters().items():
        leaf = name.split('.')[-1]
        assert len(description.split()) >= 3, (name, description)
        assert 'PhysicsParams' not in description and description.strip() != leaf, name

"""Each validation rule of head and hairstyle files, with the message it must give."""

import copy

import numpy as np
import pytest
import yaml

from hair_sim import paths
from hair_sim.modeling import HairstyleError, load_hairstyle, load_head

BASE = yaml.safe_load(open(paths.shipped_style('bob_fringe')))
P0, P1 = (repr(p['name']) for p in BASE['patches'][:2])     # patch names as messages quote
N_HAIRS = len(BASE['patches'][0]['control_hairs'])
N_POINTS = len(BASE['patches'][0]['control_hairs'][0])


def write(tmp_path, data, name='style.yaml'):
    """Write data as a style file next to a copy of the heads directory; return its path."""
    heads = tmp_path / 'heads'
    if not heads.exists():
        heads.mkdir()
        (heads / 'default_adult.yaml').write_text(
            open(paths.shipped_head('default_adult')).read())
    d = tmp_path / 'styles'
    d.mkdir(exist_ok=True)
    p = d / name
    p.write_text(data if isinstance(data, str) else yaml.safe_dump(data))
    return str(p)


def broken(mutate):
    """Return a copy of the base style with `mutate` applied."""
    d = copy.deepcopy(BASE)
    mutate(d)
    return d


def expect(tmp_path, data, *fragments):
    """Load data, expecting a HairstyleError whose message has every fragment."""
    path = write(tmp_path, data)
    with pytest.raises(HairstyleError) as info:
        load_hairstyle(path)
    msg = str(info.value)
    assert path in msg, msg
    for f in fragments:
        assert f in msg, msg
    return msg


def test_base_style_loads(tmp_path):
    """The unmodified copy loads (so every failure below is the mutation's)."""
    assert load_hairstyle(write(tmp_path, BASE)).n_strips == sum(
        p['strips'] for p in BASE['patches'])


def test_mismatched_control_point_counts(tmp_path):
    """Control hairs of a patch must have the same number of control points."""
    d = broken(lambda d: d['patches'][1]['control_hairs'][2].pop())
    n = len(BASE['patches'][1]['control_hairs'][0])
    expect(tmp_path, d, 'patch %s' % P1, 'control hair 2 has %d control points' % (n - 1),
           'same number')


def test_one_control_hair(tmp_path):
    """A patch needs at least two control hairs."""
    d = broken(lambda d: d['patches'][0].update(
        control_hairs=d['patches'][0]['control_hairs'][:1]))
    expect(tmp_path, d, 'patch %s' % P0, 'at least 2')


def test_nan_coordinate(tmp_path):
    """Non-finite numbers are refused and located."""
    d = broken(lambda d: d['patches'][0]['control_hairs'][3][4].__setitem__(1, float('nan')))
    expect(tmp_path, d, 'patch %s' % P0, 'control hair 3', 'non-finite')


def test_root_off_the_scalp(tmp_path):
    """Roots must be within the tolerance of the scalp."""
    def lift(d):
        d['patches'][1]['control_hairs'][1][0][2] += 0.02
    expect(tmp_path, broken(lift), 'patch %s' % P1, 'control hair 1 root',
           'away from the scalp')


def test_root_inside_the_head(tmp_path):
    """A root deep inside the scalp is refused too."""
    def sink(d):
        d['patches'][0]['control_hairs'][0][0] = [0.0, 0.0, 0.0]
    expect(tmp_path, broken(sink), 'control hair 0 root', 'inside the scalp')


def test_degree_not_below_point_count(tmp_path):
    """The degree along must be below the number of control points."""
    def cut(d):
        p = d['patches'][0]
        p['control_hairs'] = [h[:4] for h in p['control_hairs']]
        p['degree'] = [3, 4]
    expect(tmp_path, broken(cut), 'patch %s' % P0, 'degree along (4)',
           'below the number of control points per hair (4)')


def test_degree_across_not_below_hair_count(tmp_path):
    """The degree across must be below the number of control hairs."""
    def few(d):
        d['patches'][1]['control_hairs'] = d['patches'][1]['control_hairs'][:4]
        d['patches'][1]['degree'] = [4, 3]
    expect(tmp_path, broken(few), 'patch %s' % P1, 'degree across (4)')


def test_too_few_strips(tmp_path):
    """Strips give the columns; they cannot be fewer than the control hairs."""
    d = broken(lambda d: d['patches'][0].update(strips=3))
    expect(tmp_path, d, 'patch %s' % P0, 'fewer than its %d control hairs' % N_HAIRS)


def test_bad_knots_and_weights(tmp_path):
    """Knot vectors must fit and be clamped; weights must be positive and shaped."""
    n_knots = N_POINTS + 3 + 1
    d = broken(lambda d: d['patches'][0].update(knots_along=[0, 0, 0, 0, 1, 1, 1, 1]))
    expect(tmp_path, d, 'knots_along', 'needs %d knots' % n_knots)
    bad = [0.0] * 4 + [0.5, 0.2] + [0.7] * (n_knots - 10) + [1.0] * 4
    d = broken(lambda d: d['patches'][0].update(knots_along=bad))
    expect(tmp_path, d, 'knots_along', 'not non-decreasing')
    d = broken(lambda d: d['patches'][0].update(weights=[[1.0] * N_POINTS] * (N_HAIRS - 1)))
    expect(tmp_path, d, 'weights must have one value per control point')
    d = broken(lambda d: d['patches'][0].update(
        weights=[[1.0] * N_POINTS] * (N_HAIRS - 1) + [[0.0] * N_POINTS]))
    expect(tmp_path, d, 'weights must be positive')


def test_lod_rules(tmp_path):
    """LOD numbers are whole, in range and consistent."""
    expect(tmp_path, broken(lambda d: d['lod'].update(vertices=5)), 'lod.vertices (5)')
    expect(tmp_path, broken(lambda d: d['lod'].update(vertices='ten')), 'whole number')
    expect(tmp_path, broken(lambda d: d['lod'].update(render_columns=99)),
           'lod.render_columns = 99 is outside')
    expect(tmp_path, broken(lambda d: d['lod'].update(render_rows=4)), 'render_rows (4)')


def test_schema_errors(tmp_path):
    """Wrong shapes and unknown keys are named."""
    expect(tmp_path, broken(lambda d: d.update(colour=[1, 0, 0])), 'unknown key(s) colour')
    expect(tmp_path, broken(lambda d: d.pop('patches')), 'missing "patches"')
    expect(tmp_path, broken(lambda d: d['patches'][0]['control_hairs'][0].__setitem__(
        2, [0.1, 0.2])), 'control hair 0 point 2 has 2 coordinates')
    expect(tmp_path, broken(lambda d: d['patches'][0]['control_hairs'][1].__setitem__(
        2, ['a', 0.1, 0.2])), 'non-numeric')
    expect(tmp_path, broken(lambda d: d.update(head='no_such_head')), "head 'no_such_head'",
           'not found')
    expect(tmp_path, broken(lambda d: d['material'].update(color=[2, 0, 0])), 'material.color')


def test_malformed_yaml_and_wrong_top_level(tmp_path):
    """Malformed, truncated, non-mapping and oversized files give one clear error each."""
    expect(tmp_path, 'patches: [ {name: a, control_hairs: [[[0, 0', 'not valid YAML')
    text = open(paths.shipped_style('bob_fringe')).read()
    expect(tmp_path, text[:len(text) // 2].rsplit('\n', 3)[0] + '\n  - [0.1', 'hairstyle file')
    expect(tmp_path, '- just\n- a list\n', 'top level must be a mapping')
    expect(tmp_path, '!!python/object/apply:os.system ["true"]', 'not valid YAML')
    expect(tmp_path, 'a: ' + 'x' * (5 * 1024 * 1024), 'over the', 'byte limit')


def test_head_file_rules(tmp_path):
    """Head files: spheres need centres and positive radii; S must be inside the scalp."""
    good = yaml.safe_load(open(paths.shipped_head('default_adult')))
    for mutate, fragment in [
            (lambda d: d['scalp_spheres'][0].update(radius=-1), 'radius'),
            (lambda d: d['scalp_spheres'][1].pop('center'), 'scalp_spheres[1]'),
            (lambda d: d.update(projection_sphere={'center': [0, 0, 1], 'radius': 0.01}),
             'projection sphere must lie inside'),
            (lambda d: d['collision_spheres'][0].update(center=[0, float('inf'), 0]),
             'non-finite'),
            (lambda d: d.pop('hairline'), 'hairline')]:
        d = copy.deepcopy(good)
        mutate(d)
        p = tmp_path / 'head.yaml'
        p.write_text(yaml.safe_dump(d))
        with pytest.raises(HairstyleError) as info:
            load_head(str(p))
        assert fragment in str(info.value) and str(p) in str(info.value)
    assert np.isclose(load_head(paths.shipped_head('default_adult'))
                      .scalp[:, 3].max(), 0.075)

"""Hairstyle files and paths through the node's services: bad ones refused, nothing lost."""

import os
import subprocess
import sys

import yaml

from hair_sim import paths
from hair_sim.modeling import load_hairstyle
from helpers.ros import call_service as call

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_bad_files_are_refused_and_the_style_keeps_running(node_env, tmp_path):
    """Malformed, wrong schema, truncated, 100 MB, mismatched, NaN: success false, message."""
    from hair_sim_msgs.srv import LoadHairstyle
    _, ex, node, client = node_env
    good = open(paths.shipped_style('bob_fringe')).read()
    data = yaml.safe_load(good)
    mismatched = yaml.safe_load(good)
    mismatched['patches'][0]['control_hairs'][1].pop()
    nan = yaml.safe_load(good)
    nan['patches'][0]['control_hairs'][2][3][1] = float('nan')
    files = {
        'malformed.yaml': 'patches: [ {name: a, control_hairs: [[[0, 0',
        'schema.yaml': yaml.safe_dump({'name': 'x', 'patches': 'not a list'}),
        'truncated.yaml': good[:len(good) // 3],
        'mismatched.yaml': yaml.safe_dump(mismatched),
        'nan.yaml': yaml.safe_dump(nan),
        'unsafe.yaml': '!!python/object/apply:os.system ["touch %s/pwned"]' % tmp_path,
    }
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    with open(tmp_path / 'huge.yaml', 'wb') as f:
        f.write(b'name: huge\n' + b'#' * (100 * 2 ** 20) + b'\n')
    before = node.sim.style.name
    for name in list(files) + ['huge.yaml']:
        r = call(ex, client, LoadHairstyle, '/hair_sim/load_hairstyle',
                 LoadHairstyle.Request(path=name))
        assert not r.success and r.message, name
        assert node.sim.style.name == before
    assert not (tmp_path / 'pwned').exists()
    assert len(data['patches']) == 2
    node.sim.step(1 / 240)
    assert node.sim.style.name == before


def test_paths_stay_inside_the_hairstyle_directories(node_env, tmp_path):
    """'..', absolute paths elsewhere and symlinks leading out are refused for load and save."""
    from hair_sim_msgs.srv import LoadHairstyle, SaveHairstyle
    _, ex, node, client = node_env
    outside = tmp_path.parent / ('outside_%s' % tmp_path.name)
    outside.mkdir()
    (outside / 'secret.yaml').write_text(open(paths.shipped_style('bob_fringe')).read())
    os.symlink(outside / 'secret.yaml', tmp_path / 'link.yaml')
    os.symlink(outside, tmp_path / 'linkdir')
    for p in ('../%s/secret.yaml' % outside.name, str(outside / 'secret.yaml'), 'link.yaml',
              'linkdir/secret.yaml', '/etc/passwd', ''):
        r = call(ex, client, LoadHairstyle, '/hair_sim/load_hairstyle',
                 LoadHairstyle.Request(path=p))
        assert not r.success, p
        r = call(ex, client, SaveHairstyle, '/hair_sim/save_hairstyle',
                 SaveHairstyle.Request(path=p or 'x/../y.yaml'))
        assert not r.success, p
    assert sorted(os.listdir(outside)) == ['secret.yaml']
    r = call(ex, client, SaveHairstyle, '/hair_sim/save_hairstyle',
             SaveHairstyle.Request(path='inside.yaml'))
    assert r.success and (tmp_path / 'inside.yaml').is_file()


def test_a_save_to_a_folder_the_node_may_not_write_names_the_parameter_to_change(
        node_env, tmp_path):
    """
    Refused with the parameter a user can change, counted; saved once it lists a writable one.

    A pip install into a root-owned venv keeps the shipped folder, the only one by default,
    read-only: the refusal said "Permission denied" and nothing of hairstyle_dirs. /sys
    takes no new file even from root, so it stands in for such a folder here.
    """
    from rclpy.parameter import Parameter
    from hair_sim_msgs.srv import SaveHairstyle
    _, ex, node, client = node_env

    def save():
        return call(ex, client, SaveHairstyle, '/hair_sim/save_hairstyle',
                    SaveHairstyle.Request(path='mine'))

    assert node.set_parameters([Parameter('hairstyle_dirs',
                                          value=['', '/sys', str(tmp_path)])])[0].successful
    refused = node.refused['save_hairstyle']
    r = save()
    assert not r.success and 'Permission denied' in r.message, r.message
    assert 'hairstyle_dirs' in r.message and 'nothing written' in r.message, r.message
    assert node.refused['save_hairstyle'] == refused + 1
    assert not os.path.exists('/sys/mine.yaml')
    assert node.set_parameters([Parameter('hairstyle_dirs',
                                          value=['', str(tmp_path), '/sys'])])[0].successful
    r = save()
    assert r.success and (tmp_path / 'mine.yaml').is_file(), r.message


def test_a_save_replaces_a_file_only_when_asked_and_never_a_shipped_style(node_env, tmp_path):
    """
    A save refuses an existing file unless told to overwrite it, and any shipped style.

    The refused file is left byte for byte; with overwrite it holds the style now running.
    A shipped style is refused either way: a save to 'thesis_long' once put another style
    in the package's default. Each refusal is counted.
    """
    from hair_sim_msgs.srv import LoadHairstyle, SaveHairstyle
    _, ex, node, client = node_env

    def save(path, overwrite):
        return call(ex, client, SaveHairstyle, '/hair_sim/save_hairstyle',
                    SaveHairstyle.Request(path=path, overwrite=overwrite))

    shipped = {n: open(paths.shipped_style(n), 'rb').read()
               for n in paths.shipped_style_names()}
    first = node.sim.style.name
    r = save('mine', False)
    assert r.success, r.message
    before = (tmp_path / 'mine.yaml').read_bytes()
    other = next(n for n in shipped if n != first)
    r = call(ex, client, LoadHairstyle, '/hair_sim/load_hairstyle',
             LoadHairstyle.Request(path=other))
    assert r.success, r.message
    refused = node.refused['save_hairstyle']
    r = save('mine.yaml', False)
    assert not r.success and 'exists' in r.message and 'overwrite' in r.message
    assert (tmp_path / 'mine.yaml').read_bytes() == before
    assert load_hairstyle(str(tmp_path / 'mine.yaml')).name == first
    for name in shipped:
        for overwrite in (False, True):
            for path in (name, name + '.yaml', paths.shipped_style(name)):
                r = save(path, overwrite)
                assert not r.success and 'shipped' in r.message, (path, r.message)
    assert node.refused['save_hairstyle'] == refused + 1 + 6 * len(shipped)
    assert {n: open(paths.shipped_style(n), 'rb').read() for n in shipped} == shipped
    r = save('mine', True)
    assert r.success, r.message
    assert load_hairstyle(str(tmp_path / 'mine.yaml')).name == other
    assert sorted(os.listdir(tmp_path)) == ['mine.yaml']


def test_a_save_killed_mid_write_leaves_the_previous_file(tmp_path):
    """A process killed while saving (before its rename) leaves the old file whole."""
    target = tmp_path / 'style.yaml'
    target.write_text(open(paths.shipped_style('bob_fringe')).read())
    before = target.read_bytes()
    proc = subprocess.Popen([sys.executable, os.path.join(HERE, 'helpers', 'slow_save.py'),
                             paths.shipped_style('thesis_long'), str(target)],
                            stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == 'writing'
    proc.kill()
    proc.wait(timeout=10)
    assert target.read_bytes() == before
    assert load_hairstyle(str(target)).name == 'bob_fringe'

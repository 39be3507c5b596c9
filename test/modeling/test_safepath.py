"""Hairstyle paths from requests: what a careless or hostile client may send."""

import os

import pytest

from hair_sim.modeling.errors import HairstyleError
from hair_sim.modeling.safepath import resolve_save_path, resolve_style_path


@pytest.mark.parametrize('request_path, why', [
    ('sub/', 'no file name'),                     # was saved as sub/.yaml
    ('.', 'no file name'),                        # was saved as ..yaml
    ('..', 'no file name'),                       # was saved as ...yaml
    ('.hidden', 'no file name'),
    ('sub/.yaml', 'no file name'),
    ('new\nline', 'control characters'),          # was saved under that name
    ('tab\there.yaml', 'control characters'),
    ('bell\x07', 'control characters'),
    ('del\x7f.yaml', 'control characters'),
    ('a' * 251, 'longer than 255 bytes'),         # 256 with .yaml: the OS's ENAMETOOLONG
    ('\u00e9' * 126, 'longer than 255 bytes'),    # 252 bytes in UTF-8, 257 with .yaml
    ('x/../y', '".." is not allowed'),
    ('nul\x00.yaml', 'malformed'),
    ('', 'empty'),
    ('   ', 'empty'),
])
@pytest.mark.parametrize('must_exist', [False, True])
def test_a_path_that_names_no_plain_file_is_refused_and_nothing_is_written(
        tmp_path, request_path, why, must_exist):
    """Check each refusal's reason, for saves and loads, with the folder left as it was."""
    (tmp_path / 'sub').mkdir()
    with pytest.raises(HairstyleError, match=why):
        resolve_style_path(request_path, [str(tmp_path)], must_exist=must_exist)
    assert sorted(os.listdir(tmp_path)) == ['sub'] and os.listdir(tmp_path / 'sub') == []


@pytest.mark.parametrize('request_path, name', [
    ('mine', 'mine.yaml'),
    ('mine.yaml', 'mine.yaml'),
    ('  mine  ', 'mine.yaml'),
    ('sub/mine', os.path.join('sub', 'mine.yaml')),
    ('sp ace', 'sp ace.yaml'),
    ('\u00fcn\u00ef\u00e7\u00f8d\u00e9', '\u00fcn\u00ef\u00e7\u00f8d\u00e9.yaml'),
    ('a' * 250, 'a' * 250 + '.yaml'),             # 255 bytes: the longest a name may be
    ('-rf', '-rf.yaml'),
])
def test_a_plain_name_resolves_inside_the_folder(tmp_path, request_path, name):
    """Check that ordinary names, unicode and the longest name still resolve for a save."""
    (tmp_path / 'sub').mkdir()
    path = resolve_save_path(request_path, [str(tmp_path)], overwrite=False)
    assert path == os.path.join(os.path.realpath(tmp_path), name)
    with open(path, 'w') as f:                    # the OS takes the name
        f.write('x')

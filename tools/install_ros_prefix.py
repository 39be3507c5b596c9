"""
Make the editable hair_sim install visible to ROS tools in the venv prefix.

pip's editable install puts the console scripts in <venv>/bin but skips setup.py's
data_files. A full ROS install (colcon) puts them under the package prefix instead:
the ament index marker, share/hair_sim/{package.xml,config} and lib/hair_sim/<script>,
which is where `ros2 run hair_sim X` looks. This writes that same layout into the venv
prefix: package.xml and the marker are copied, config/ is a symlink to the work tree (edits
stay live, as the code does), and every console script is copied into lib/hair_sim/.
"""

from importlib import metadata
import os
import shutil
import sys

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _copy_atomic(src, dst):
    """Copy src to dst through a temporary file and a rename."""
    os.makedirs(os.path.dirname(dst), exist_ok=True)
    tmp = os.path.join(os.path.dirname(dst), '.' + os.path.basename(dst) + '.tmp')
    shutil.copy2(src, tmp)
    os.replace(tmp, dst)


def main(venv):
    """Install the ament index marker, share/ files and lib/ scripts of hair_sim."""
    venv = os.path.abspath(venv)
    _copy_atomic(os.path.join(HERE, 'resource', 'hair_sim'),
                 os.path.join(venv, 'share', 'ament_index', 'resource_index', 'packages',
                              'hair_sim'))
    share = os.path.join(venv, 'share', 'hair_sim')
    _copy_atomic(os.path.join(HERE, 'package.xml'), os.path.join(share, 'package.xml'))
    link = os.path.join(share, 'config')
    if os.path.islink(link) or os.path.exists(link):
        if os.path.isdir(link) and not os.path.islink(link):
            shutil.rmtree(link)
        else:
            os.remove(link)
    os.symlink(os.path.join(HERE, 'config'), link)
    dest = os.path.join(venv, 'lib', 'hair_sim')
    scripts = sorted(ep.name for ep in metadata.distribution('hair_sim').entry_points
                     if ep.group == 'console_scripts')
    for name in scripts:
        src = os.path.join(venv, 'bin', name)
        if not os.path.isfile(src):
            sys.exit('console script %s is not in %s/bin: was hair_sim installed with a pip '
                     'that follows setup.cfg\'s [develop] script_dir? (make setup pins pip)'
                     % (name, venv))
        _copy_atomic(src, os.path.join(dest, name))
    print('hair_sim registered in the ament prefix %s; ros2 run scripts: %s'
          % (venv, ', '.join(scripts) or '(none yet)'))


if __name__ == '__main__':
    main(sys.argv[1] if len(sys.argv) > 1 else '.venv')

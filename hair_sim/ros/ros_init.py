"""
rclpy.init for hair_sim's programs: a log folder ROS cannot make costs the log files only.

ROS writes its log files under ROS_LOG_DIR, else ROS_HOME/log, else ~/.ros/log. Where that
cannot be made (HOME read-only, as under a service manager or in a container; HOME unset;
a full or read-only disk), rclpy.init raised "failed to initialize logging", and every
program ended at start with a traceback. Here the programs start again without the log
files (ROS's --disable-external-lib-logs): the console gets every line as before, and one
line says why there are no files and what to set.
"""

import os
import sys

import rclpy


def init_ros(args=None, context=None):
    """
    Call rclpy.init(args, context); when the log folder cannot be made, again without files.

    A failure other than the log folder's is raised as rclpy raised it (a RuntimeError:
    arguments rcl cannot parse, a params file missing).
    """
    try:
        rclpy.init(args=args, context=context)
        return
    except RuntimeError as exc:
        if 'failed to initialize logging' not in str(exc):
            raise
        why = str(exc).split(', at ')[0]
    rclpy.try_shutdown(context=context)
    argv = list(sys.argv if args is None else args)
    rclpy.init(args=argv + ['--ros-args', '--disable-external-lib-logs'], context=context)
    print('%s: ROS log files are off (%s); set ROS_LOG_DIR to a folder this user can '
          'write to keep them; the console still gets every line'
          % (os.path.basename(argv[0]) if argv else 'hair_sim', why), file=sys.stderr,
          flush=True)

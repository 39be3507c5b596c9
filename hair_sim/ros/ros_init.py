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


def init_ros(args=None):
    """
    Call rclpy.init(args); when the log folder cannot be made, again without files.

    The default context only: rclpy keeps a Context whose init failed as initialised, so
    one given here could not be initialised again (python -m hair_sim.warmup, which gave
    its own, ended in "Context.init() must only be called once" for a user whose HOME
    cannot hold ~/.ros/log); rclpy.try_shutdown() replaces the default one.

    Any other failure ends the program with one line that says it (SystemExit): rcl's
    RuntimeError came as a traceback, where ROS_DOMAIN_ID=abc, say, was its last line.
    """
    argv = list(sys.argv if args is None else args)
    program = os.path.basename(argv[0]) if argv else 'hair_sim'
    try:
        rclpy.init(args=args)
        return
    except RuntimeError as exc:
        why = str(exc).split(', at ')[0]
        if 'failed to initialize logging' not in why:
            raise SystemExit('%s: ROS could not start: %s' % (program, why)) from None
    rclpy.try_shutdown()
    rclpy.init(args=argv + ['--ros-args', '--disable-external-lib-logs'])
    print('%s: ROS log files are off (%s); set ROS_LOG_DIR to a folder this user can '
          'write to keep them; the console still gets every line'
          % (program, why), file=sys.stderr, flush=True)

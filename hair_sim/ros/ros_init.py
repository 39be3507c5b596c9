"""
rclpy.init for hair_sim's programs: a log folder ROS cannot make costs the log files only.

ROS writes its log files under ROS_LOG_DIR, else ROS_HOME/log, else ~/.ros/log. Where that
cannot be made (HOME read-only, as under a service manager or in a container; HOME unset;
a full or read-only disk), rclpy.init raised "failed to initialize logging", and every
program ended at start with a traceback. Here the programs start again without the log
files (ROS's --disable-external-lib-logs): the console gets every line as before, and one
line says why there are no files and what to set.

A ROS_DOMAIN_ID over FAST_DDS_MAX_DOMAIN is refused before ROS starts, in one line: Fast DDS
ended the program itself (exit code 1, from inside the node's creation) with only its own
"Calculated port number is too high" and no word of which program or setting. Not where a
Fast DDS XML profile is given: it may move the ports, and Fast DDS then judges the domain.
"""

import os
import sys

import rclpy

# Fast DDS maps a domain to UDP ports 7400 + 250 * domain (and a few more): past 232 they
# are over 65535, and it ends the program (233 did, 232 ran, measured with hair_sim_node)
FAST_DDS_MAX_DOMAIN = 232
# where Fast DDS reads an XML profile that may move its ports (portBase, domainIDGain)
FAST_DDS_PROFILE_VARIABLES = ('FASTDDS_DEFAULT_PROFILES_FILE', 'FASTRTPS_DEFAULT_PROFILES_FILE')
FAST_DDS_PROFILE_FILES = ('DEFAULT_FASTDDS_PROFILES.xml', 'DEFAULT_FASTRTPS_PROFILES.xml')


def domain_problem(environ=os.environ):
    """
    Return why ROS_DOMAIN_ID cannot be used with this RMW, or None.

    Only a number past what Fast DDS (ROS 2 Jazzy's default RMW) takes on its default
    ports is said here, and not where an XML profile may move them; any other value is
    left to rcl, which says what is wrong with it.
    """
    value = environ.get('ROS_DOMAIN_ID', '').strip()
    if not (value.isascii() and value.isdigit()) or int(value) <= FAST_DDS_MAX_DOMAIN:
        return None
    if any(environ.get(name) for name in FAST_DDS_PROFILE_VARIABLES) or \
            any(os.path.exists(name) for name in FAST_DDS_PROFILE_FILES):
        return None     # (a profile may set other ports: Fast DDS judges them itself)
    rmw = rclpy.get_rmw_implementation_identifier()
    if not rmw.startswith('rmw_fastrtps'):
        return None
    return ('ROS_DOMAIN_ID is %s; %s (Fast DDS) takes 0 to %d, the domains whose UDP ports '
            'are under 65536, and ROS 2 advises 0 to 101'
            % (value if len(value) <= 20 else value[:20] + '...', rmw, FAST_DDS_MAX_DOMAIN))


def init_ros(args=None):
    """
    Call rclpy.init(args); when the log folder cannot be made, again without files.

    The default context only: rclpy keeps a Context whose init failed as initialised, so
    one given here could not be initialised again (python -m hair_sim.warmup, which gave
    its own, ended in "Context.init() must only be called once" for a user whose HOME
    cannot hold ~/.ros/log); rclpy.try_shutdown() replaces the default one.

    Any other failure ends the program with one line that says it (SystemExit): rcl's
    RuntimeError came as a traceback, where ROS_DOMAIN_ID=abc, say, was its last line; so
    does a domain Fast DDS cannot take (domain_problem), before ROS starts.
    """
    argv = list(sys.argv if args is None else args)
    program = os.path.basename(argv[0]) if argv else 'hair_sim'
    why = domain_problem()
    if why:
        raise SystemExit('%s: ROS could not start: %s' % (program, why))
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

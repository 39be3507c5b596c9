"""
hair_sim_demo: the node with the sample style, a scripted head and wind, and meshcat.

The head driver runs as its own process (hair_sim.ros.head_driver), like a real tracker:
it publishes PoseStamped on head_pose at 100 Hz and Wind gusts on wind. The node runs here
on a single-threaded executor. Everything goes through real topics. ROS arguments after
--ros-args (a namespace, remaps, a params file) go to both processes.

    hair_sim_demo [--duration S] [--style NAME] [--no-meshcat] [--ros-args ...]
"""

import argparse
import json
import os
import subprocess
import sys
import time

import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor

from hair_sim.arguments import seconds
from hair_sim.ros.ros_init import init_ros


def split_ros_args(argv):
    """Return (the demo's own arguments, the ROS arguments from the first --ros-args on)."""
    argv = list(argv)
    if '--ros-args' in argv:
        i = argv.index('--ros-args')
        return argv[:i], argv[i:]
    return argv, []


def start_driver(ros_args, rate=100.0):
    """Start the head driver process with the same ROS arguments; return the Popen."""
    cmd = [sys.executable, '-m', 'hair_sim.ros.head_driver', '--rate', str(rate),
           '--parent-pid', str(os.getpid())] + list(ros_args)
    return subprocess.Popen(cmd)


def main(argv=None):
    """Run the demo until Ctrl-C or --duration seconds."""
    argv = sys.argv[1:] if argv is None else list(argv)
    own, ros_args = split_ros_args(argv)
    parser = argparse.ArgumentParser(prog='hair_sim_demo', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--duration', type=seconds, default=0.0,
                        help='seconds (0: until Ctrl-C)')
    parser.add_argument('--style', default='thesis_long', help='hairstyle name')
    parser.add_argument('--no-meshcat', action='store_true', help='ROS topics only')
    args = parser.parse_args(own)
    from hair_sim.ros.node import HairSimNode, ignore_interrupts_while_stopping

    # the demo's choices first, so that the user's --ros-args -p ... override them
    # (the name as a YAML string: rcl reads a -p value as YAML, and '', '[1, 2]' or 'a: b'
    # failed in rcl's argument parser with its traceback)
    node_args = ['hair_sim_demo', '--ros-args', '-p', 'hairstyle:=%s' % json.dumps(args.style),
                 '-p', 'meshcat.enabled:=%s' % ('false' if args.no_meshcat else 'true')]
    node_args += ros_args
    try:
        init_ros(node_args)
    except RuntimeError as exc:     # rcl cannot parse them: a params file missing, not YAML
        print('hair_sim_demo: %s' % exc, file=sys.stderr)
        return 1
    node = driver = None
    code = 0
    try:
        node = HairSimNode()
        driver = start_driver(ros_args)
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        start = time.monotonic()
        printed = False
        while rclpy.ok():
            try:
                executor.spin_once(timeout_sec=0.1)
            except (KeyboardInterrupt, ExternalShutdownException):
                raise
            except Exception as exc:                  # noqa: B902 - count it, go on
                if not rclpy.ok():                    # SIGTERM shut the context: a stop
                    break
                node._internal_error('executor', exc)
            if not printed and node.meshcat_url:
                print('URL %s' % node.meshcat_url, flush=True)
                printed = True
            if args.duration and time.monotonic() - start > args.duration:
                break
            if driver.poll() is not None:
                print('hair_sim_demo: the head driver exited (%d)' % driver.returncode,
                      file=sys.stderr)
                code = 1
                break
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (ValueError, ParameterException) as exc:
        print('hair_sim_demo: %s' % exc, file=sys.stderr)
        code = 1
    finally:
        ignore_interrupts_while_stopping()
        if driver is not None and driver.poll() is None:
            driver.terminate()
            try:
                driver.wait(timeout=5)
            except subprocess.TimeoutExpired:
                driver.kill()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return code


if __name__ == '__main__':
    sys.exit(main())

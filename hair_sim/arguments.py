"""argparse types the command-line programs share: numbers refused before anything runs."""

import argparse
import math


def seconds(text):
    """Return a finite, non-negative number of seconds, at most a day (an argparse type)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError('%r is not a number of seconds' % text) from None
    if not (math.isfinite(value) and 0.0 <= value <= 86400.0):
        raise argparse.ArgumentTypeError('%r s: give 0 to 86400 s' % text)
    return value


def rate_hz(text):
    """Return a finite rate above 0 and at most 10 kHz (an argparse type)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError('%r is not a rate in Hz' % text) from None
    if not (math.isfinite(value) and 0.0 < value <= 10000.0):
        raise argparse.ArgumentTypeError('%r Hz: give more than 0 and at most 10000 Hz' % text)
    return value


def namespace(text):
    """Return text as an absolute ROS namespace, 'alice/' giving '/alice' (an argparse type)."""
    from rclpy.exceptions import InvalidNamespaceException
    from rclpy.validate_namespace import validate_namespace
    ns = '/' + text.strip('/')
    try:
        validate_namespace(ns)
    except InvalidNamespaceException as exc:
        why = str(exc).splitlines()[0].replace('Invalid namespace: ', '').rstrip(':')
        raise argparse.ArgumentTypeError('%r is not a ROS namespace: %s' % (text, why)) from None
    return ns

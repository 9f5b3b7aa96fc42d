"""rclpy.utilities for Python in the IDE page."""

import sys

from rclpy.context import default_context


def get_default_context(*, shutting_down=False):
    return default_context()


def ok(*, context=None):
    return (context or default_context()).ok()


def remove_ros_args(args=None):
    args = sys.argv if args is None else args
    out, skip = [], False
    inside = False
    for a in args:
        if a == "--ros-args":
            inside = True
            continue
        if inside:
            if a == "--":
                inside = False
            continue
        if not skip:
            out.append(a)
    return out


def get_rmw_implementation_identifier():
    return "rmw_rosgate_page"


def timeout_sec_to_nsec(timeout_sec):
    if timeout_sec is None or timeout_sec < 0:
        return -1
    return int(float(timeout_sec) * 1e9)

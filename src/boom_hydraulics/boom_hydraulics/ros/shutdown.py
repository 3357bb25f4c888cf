"""Leaving ROS at the end of a program, where a signal may be doing the same at that moment."""

from __future__ import annotations

import rclpy


def shut_down() -> None:
    """rclpy.try_shutdown(), where a signal may be shutting the context down at the same moment
    (rclpy's own SIGINT and SIGTERM handling does, in its signal handler thread): its
    'rcl_shutdown already called' is then what was asked for. Any other error is raised.
    A Ctrl-C just after boom_sim's first log line gave that traceback once (test_node_stamps)."""
    try:
        rclpy.try_shutdown()
    except Exception as exc:
        if rclpy.ok() or "already called" not in str(exc):
            raise

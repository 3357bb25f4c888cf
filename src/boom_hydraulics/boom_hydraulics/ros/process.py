"""The ``boom_sim`` process: check the arguments, start the node, spin, and shut down.

A bad params file or ``-p`` value is one line and exit status 2; a bag that cannot be started,
or a recording that failed, exit status 1; a SIGINT or SIGTERM while the node starts or runs
is a clean stop (0), and from the first one on a second one cannot interrupt finishing the bag.
"""

from __future__ import annotations

import signal
import sys
import threading
from typing import Any

import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException

from ..errors import BoomHydraulicsError, ConfigError
from ..programs import NODE_STOPPED_WHILE_STARTING, dropped_interrupts_unreported, ignore_stop_signals
from . import node_parameters as ros_parameters
from .node import BoomSimNode
from .shutdown import shut_down


def _fail(message: str) -> None:
    print(f"boom_sim: error: {message}", file=sys.stderr, flush=True)
    raise SystemExit(2)


def _shield_signals() -> None:
    """From the first SIGINT or SIGTERM on, a second one (a terminal's Ctrl-C and the one
    ros2 launch forwards arrive together) must not interrupt finishing the bag."""

    def note(_signum: int, _frame: Any) -> None:
        print("boom_sim: still finishing; it ends by itself", file=sys.stderr, flush=True)

    while True:
        try:
            for signum in (signal.SIGINT, signal.SIGTERM):
                signal.signal(signum, note)
            return
        except KeyboardInterrupt:  # the second of two at once, landing while the shield goes up:
            continue  # up again (make test met it once: a traceback, and the bag left unfinished)


def _finish(node: BoomSimNode, started: bool) -> bool:
    """Stop the loop, finish the bag and say where it is, then leave the ROS graph; False
    when the recording failed (the bag is left for boom-bag-recover)."""
    node.stopping.set()
    if node.loop.is_alive():
        node.loop.join(timeout=5.0)
    recorded = node.recording.finish(started)
    node.destroy()
    return recorded


class _Start(threading.Thread):
    """``node.start()`` in a thread of its own: a Ctrl-C's KeyboardInterrupt, which only the
    main thread gets, lands in the main thread's wait for it, and cannot cut the bag's start
    short (a folder or a file begun and never finished)."""

    def __init__(self, node: BoomSimNode) -> None:
        super().__init__(name="boom_sim_start", daemon=True)
        self.node = node
        self.error: BaseException | None = None
        # (not join() or is_alive(): in Python 3.11 a join cut short by KeyboardInterrupt can
        # leave the thread marked as ended while it still runs)
        self.began, self.ended = threading.Event(), threading.Event()

    def run(self) -> None:
        self.began.set()
        try:
            self.node.start()
        except BaseException as exc:  # handed to the main thread by wait()
            self.error = exc
        finally:
            self.ended.set()

    def wait(self) -> None:
        """Wait for the start to end (a signal may interrupt the wait, not the start), and
        raise what it raised."""
        self.ended.wait()
        if self.error is not None:
            raise self.error

    def finish(self) -> None:
        """After a signal cut a wait short: let a start that runs end (one the signal kept
        from being launched at all, within ``start()``, never begins)."""
        if not self.ended.is_set() and self.began.wait(timeout=1.0):
            self.ended.wait()


def _stopped_while_starting() -> None:
    print(f"boom_sim: {NODE_STOPPED_WHILE_STARTING}", file=sys.stderr, flush=True)


def main(args: list[str] | None = None) -> None:
    argv = sys.argv if args is None else args
    if any(a in ("-h", "--help") for a in ros_parameters.user_args(argv)[1:]):
        print(ros_parameters.usage())
        return
    try:
        for path in ros_parameters.params_files(argv):
            ros_parameters.check_params_file(path)
    except ConfigError as exc:
        _fail(str(exc))
    # The loop thread must get the GIL soon after its deadline; CPython's default 5 ms
    # switch interval showed as a 16 ms p99 tick period at 100 Hz.
    sys.setswitchinterval(0.0005)
    try:
        rclpy.init(args=args)
    except Exception as exc:  # rcl's argument parser: a malformed -p or --ros-args rule
        _fail(f"cannot read the ROS arguments: {str(exc).splitlines()[0]}")
    # A Ctrl-C whose KeyboardInterrupt Python dropped is no traceback: one landing in llvmlite's
    # cache callback while the node compiles showed "Exception ignored on calling ctypes callback
    # function" before the one line. The signal has shut the ROS context down all the same
    # (rclpy's handler, just after), and the start and the spin end on that.
    try:
        with dropped_interrupts_unreported(lambda: True):
            _run(argv)
    finally:
        ignore_stop_signals()


def _run(argv: list[str]) -> None:
    """Start the node, spin until a signal or a failure, then finish (rclpy initialised with
    the command line ``argv``)."""
    try:
        node = BoomSimNode()
    except (BoomHydraulicsError, ParameterException) as exc:  # a bad params file or -p value
        shut_down()
        _fail(ros_parameters.on_command_line(str(exc), argv))
    except (KeyboardInterrupt, ExternalShutdownException):  # SIGINT/SIGTERM while it compiles or starts
        node = None
    except Exception:
        if rclpy.ok():
            raise
        node = None  # a signal shut the context down under the start-up: a clean stop too
    if node is None:
        while True:  # (the try here, not in the call: a second Ctrl-C landed on _shield_signals' first line)
            try:
                _shield_signals()
                break
            except KeyboardInterrupt:
                continue
        shut_down()  # (nothing to do where the signal has shut the context down already)
        _stopped_while_starting()
        return
    started = False
    start_error: str | None = None
    start: _Start | None = None
    try:
        # (a signal may come from here on: the first log line is out; a KeyboardInterrupt is
        # raised where Python code runs next, so no call stands outside this try)
        start = _Start(node)
        start.start()
        start.wait()
        started = True
        node.motion.spin_in_background()
        rclpy.spin(node)
    except BoomHydraulicsError as exc:  # the bag cannot be started (a full disk, a read-only folder)
        if started:
            raise
        start_error = str(exc)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:
        # SIGINT/SIGTERM shut the context down; the executor may then fail building its
        # wait set (RCLError) instead of raising ExternalShutdownException: that is a
        # clean shutdown too. Anything else is a real error.
        if rclpy.ok():
            raise
    finally:
        _shield_signals()
        if start is not None:
            start.finish()  # a signal came during the start: let it end, then finish what it began
        recorded = _finish(node, started)
        shut_down()
    start_error = start_error or node.start_failure  # (on a shared clock the bag starts at its first tick)
    if start_error is not None:
        print(f"boom_sim: error: {start_error}", file=sys.stderr, flush=True)
        raise SystemExit(1)
    if not started and node.recording.recorder is None:
        _stopped_while_starting()
    if not recorded:
        raise SystemExit(1)


if __name__ == "__main__":
    main()

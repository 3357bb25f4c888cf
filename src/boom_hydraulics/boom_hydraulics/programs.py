"""What the command-line programs share (cli/ and the ROS ones, boom-replay and boom-demo):
arguments that fail as one line, and exit codes.

Exit codes: 0 done, 1 the work failed (a simulation, a file, a bag), 2 bad arguments or
configuration (ConfigError), 130 interrupted (Ctrl-C, SIGINT), 143 terminated (SIGTERM).
An interrupted or terminated tool stops as a failing one does: what it was writing is
removed, what was there before stays.
"""

from __future__ import annotations

import argparse
import errno
import json
import os
import signal
import sys
import threading
import traceback
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from typing import Any, NoReturn, TypeVar

from .errors import BoomHydraulicsError, ConfigError

T = TypeVar("T")
R = TypeVar("R")

#: What the node (boom_sim) says when a signal stops it before it runs (exit status 0, as for any
#: stop of a node): ros.process once its modules are loaded, entry_points while they load.
NODE_STOPPED_WHILE_STARTING = "stopped while starting; nothing was recorded"


def ignore_stop_signals() -> None:
    """From here on a SIGINT or SIGTERM changes nothing: a program that is done (its line said)
    ends as it decided. A second Ctrl-C, or the one ``ros2 launch`` forwards with the terminal's,
    would otherwise interrupt its last line with a traceback; and Python's shutdown puts back the
    default action of a signal that has a Python handler, so that a second Ctrl-C in its half
    second killed the process (status 130, not the one decided). An ignored signal stays ignored."""
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, signal.SIG_IGN)


class RaisingParser(argparse.ArgumentParser):
    """argparse that raises ConfigError instead of exiting, so every error ends as one line."""

    def error(self, message: str) -> None:  # type: ignore[override]
        raise ConfigError(f"{self.prog}: {message}")


class DefaultsFormatter(argparse.HelpFormatter):
    """Help that names each option's default once: added where the help text does not
    already say it, and left out where there is nothing to say (None, off, empty)."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if "default" in text or not action.option_strings or action.default in (None, False, [], argparse.SUPPRESS):
            return text
        return f"{text} (default: %(default)s)"


def summary(doc: str | None) -> str:
    """The first line of a module docstring as plain text for ``--help`` (no reST markup)."""
    return (doc or "").strip().splitlines()[0].replace("``", "")


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised like Ctrl-C so that the same clean-up runs (temporary files removed)."""


#: The stop signals received while run_main's body runs. Python drops an exception raised in a
#: finalizer (``__del__``, a weakref callback: "Exception ignored in ..."), and a signal handler
#: runs inside whatever code is running, a finalizer too: loading the compiled kernel disposes
#: of many LLVM objects. :func:`raise_pending` raises such a lost signal again.
_PENDING: list[int] = []


def _terminate(signum: int, frame: object) -> None:
    _PENDING.append(signum)
    raise Terminated()


def _interrupt(signum: int, frame: object) -> None:
    _PENDING.append(signum)
    raise KeyboardInterrupt


@contextmanager
def dropped_interrupts_unreported(when: Callable[[], bool]) -> Iterator[None]:
    """While it runs, a stop signal's exception (KeyboardInterrupt, or Terminated) that Python
    dropped is no traceback for the user, where ``when()`` says the stop goes on all the same;
    anything else reaches the hook in place. Python drops an exception raised in a finalizer or
    a ctypes callback ("Exception ignored in ..."), and a signal handler runs inside whatever
    code is running: loading or compiling the kernels disposes of many LLVM objects and calls
    llvmlite's cache callback. The same goes for llvmlite's finalizer failing on an object whose
    making or closing such an exception cut in two (see :func:`_left_half_made`)."""
    hook = sys.unraisablehook

    def unraisable(dropped: Any) -> None:
        exc = getattr(dropped, "exc_value", None)
        if not ((isinstance(exc, KeyboardInterrupt) or _left_half_made(dropped)) and when()):
            hook(dropped)

    sys.unraisablehook = unraisable
    try:
        yield
    finally:
        sys.unraisablehook = hook


def _left_half_made(dropped: Any) -> bool:
    """Whether ``dropped`` is an llvmlite finalizer (``__del__``) missing an attribute of its
    object: one whose ``__init__`` or ``close()`` an exception cut between two statements, as
    only a signal's does (llvmlite 0.50). After a node's start stopped by Ctrl-C twice they
    showed as "Exception ignored in ObjectRef.__del__ ... AttributeError: _as_parameter_" (a
    close cut after ``del self._as_parameter_``) and "in OutputString.__del__ ...
    AttributeError: _ptr" (an ``__init__`` cut before ``self._ptr = ...``)."""
    exc = getattr(dropped, "exc_value", None)
    finalizer = getattr(dropped, "object", None)
    where = getattr(finalizer, "__module__", None) or ""
    return (
        isinstance(exc, AttributeError)
        and getattr(finalizer, "__name__", None) == "__del__"
        and where.startswith("llvmlite.")
    )


def raise_pending() -> None:
    """Raise again the Ctrl-C or SIGTERM that run_main's body received, if one came: a long loop
    calls it between its slices, so that a signal whose exception a finalizer swallowed still
    stops the run (a sweep once ran its day-long batch to the end after Ctrl-C). In a thread
    running work under :func:`cancellable`, raise CalledOffError once that work was called off.

    (A signal lands in the main thread only: a loop in another thread learns of it here.)"""
    if _PENDING:
        raise Terminated() if _PENDING[-1] == signal.SIGTERM else KeyboardInterrupt
    called_off = getattr(_WORK, "called_off", None)
    if called_off is not None and called_off.is_set():
        raise CalledOffError()


class CalledOffError(BaseException):
    """Work in a thread whose result is no longer wanted (:func:`cancellable`): a BaseException,
    as KeyboardInterrupt, so that no ``except Exception`` of the work takes it for its own."""


#: The Event of the work the current thread runs under cancellable, if any.
_WORK = threading.local()


def cancellable(called_off: threading.Event, fn: Callable[[T], R], item: T) -> R:
    """``fn(item)``, in a thread of a pool, stopped (CalledOffError) at its next :func:`raise_pending`
    once ``called_off`` is set: its caller stopped taking results (a Ctrl-C, a full disk)."""
    _WORK.called_off = called_off
    try:
        return fn(item)
    finally:
        del _WORK.called_off


#: What to do about the OSErrors a user meets writing results.
_ADVICE = {
    errno.ENOSPC: "the disk is full: free some space or write to another disk",
    errno.EDQUOT: "the disk quota is used up; free some space or write elsewhere",
    errno.EROFS: "write to a folder on a writable disk instead",
    errno.EACCES: "no permission; write somewhere you may, or change the permissions",
    errno.EPERM: "not permitted; write somewhere you may",
    errno.ENOENT: "no such file or folder; check the path",
}


def describe_os_error(exc: OSError) -> str:
    """One line on ``exc``: the file it is about (when known), what went wrong and what to do."""
    what = exc.strerror or str(exc) or type(exc).__name__
    advice = _ADVICE.get(exc.errno)
    text = f"{what} ({advice})" if advice else what
    return f"{exc.filename}: {text}" if exc.filename else text


def run_main(prog: str, body: Callable[[], int]) -> int:
    """``body()``, with this package's errors printed as ``PROG: error: ...`` and turned into exit codes.

    SIGTERM is turned into an exception like Ctrl-C while ``body`` runs, so that a terminated
    tool cleans up as an interrupted one does (and exits 143, 130 for Ctrl-C). Both are also
    recorded for :func:`raise_pending`."""
    _PENDING.clear()  # (a signal that came after an earlier run_main in this process cleared it)
    previous = _install_terminate()
    interrupt = _install_interrupt()
    try:
        # (the body's stop signals are recorded: raise_pending raises a dropped one again)
        with dropped_interrupts_unreported(lambda: bool(_PENDING)):
            return body()
    except BoomHydraulicsError as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return 2 if isinstance(exc, ConfigError) else 1
    except OSError as exc:
        print(f"{prog}: error: {describe_os_error(exc)}", file=sys.stderr)
        return 1
    except MemoryError:
        print(f"{prog}: error: out of memory; ask for a smaller run (fewer points or samples)", file=sys.stderr)
        return 1
    except Terminated:
        return _stopped(prog, signal.SIGTERM)
    except KeyboardInterrupt:
        return _stopped(prog, signal.SIGINT)
    except Exception:
        # a stop signal's exception that the code it landed in turned into another (matplotlib's
        # drawing gave a ValueError for one, once): the stop that was asked for, not a traceback
        if not _PENDING:
            raise
        return _stopped(prog, _PENDING[-1])
    finally:
        _PENDING.clear()
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
        if interrupt is not None and signal.getsignal(signal.SIGINT) is _interrupt:
            signal.signal(signal.SIGINT, interrupt)


def stop_words(signum: int) -> str:
    """How a program's line names the stop signal ``signum``."""
    return "terminated (SIGTERM)" if signum == signal.SIGTERM else "interrupted (Ctrl-C)"


def _stopped(prog: str, signum: int) -> int:
    """The line and exit status of a run stopped by ``signum`` (SIGINT: 130, SIGTERM: 143)."""
    print(f"{prog}: error: {stop_words(signum)}; stopped, and what it was writing was not kept", file=sys.stderr)
    return 128 + signum


def stop_handled() -> None:
    """The stop signals run_main's body received so far are dealt with: a program that takes a
    Ctrl-C as its way to end (boom-replay, boom-sim live) says so where it catches it, so that an
    exception after it is reported as what it is, not as the stop (run_main, stop_received)."""
    _PENDING.clear()


def stop_received() -> int | None:
    """The stop signal (SIGINT or SIGTERM) that run_main's body received last, or None: for a
    program that reports a stop in its own words, where an exception other than the signal's
    came out of the code the signal landed in."""
    return _PENDING[-1] if _PENDING else None


def _install_interrupt() -> object | None:
    """Route SIGINT to :func:`_interrupt` (KeyboardInterrupt, as Python's own handler, and
    recorded) where Python's own handler is in place (a ROS tool's rclpy installs its own
    later, in front of it); return the handler it replaced, or None where it installed nothing."""
    try:
        if signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
            return None
        return signal.signal(signal.SIGINT, _interrupt)
    except ValueError:  # not the main thread
        return None


def _install_terminate() -> object | None:
    """Route SIGTERM to :class:`Terminated` (main thread only, where Python allows handlers);
    return the handler it replaced, or None where it installed nothing."""
    try:
        return signal.signal(signal.SIGTERM, _terminate)
    except ValueError:  # not the main thread
        return None


class Forked:
    """``work()`` in a child process forked from this one, beside what this process does next:
    a share of a program's work that runs on another core without waiting for the GIL (the
    sweep's plots: the process that draws them, and half of them in a child of that one).
    :meth:`wait` waits for it and raises here what it raised; a stop (Ctrl-C reaches both
    processes from the terminal) ends it quietly, and :meth:`stop` ends it from here. Fork
    only where :func:`can_fork`; a fork the system refuses raises OSError, and nothing is
    left of it.

    The stop signals are blocked across the fork: one that came then is taken by each
    process where it can take it, the child inside its own handling (which never returns to
    the parent's code), the parent once the child is known (and stopped with it).
    """

    def __init__(self, work: Callable[[], Any]) -> None:
        for stream in (sys.stdout, sys.stderr):  # (what is buffered is this process's to write)
            stream.flush()
        read, write = os.pipe()
        self.pid, self._read, self._reaped = -1, read, False
        signal.pthread_sigmask(signal.SIG_BLOCK, _STOPS)
        try:
            self.pid = os.fork()
            if self.pid == 0:  # the child, which never returns from here
                _child(work, read, write)
        except BaseException:  # the system refused the fork (the stops still blocked: nothing cuts this short)
            os.close(read)
            os.close(write)
            self._reaped = True
            signal.pthread_sigmask(signal.SIG_UNBLOCK, _STOPS)
            raise
        os.close(write)
        try:
            signal.pthread_sigmask(signal.SIG_UNBLOCK, _STOPS)  # (a stop that came meanwhile lands here)
        except BaseException:
            self.stop()
            raise

    def wait(self) -> Any:
        """Wait for the child to end and return what ``work()`` returned (made of what JSON
        holds: a list, a dict, a string, a number); raise its failure here: an OSError as an
        OSError, a stop as the stop, a failure of this package as one, running out of memory as
        MemoryError, anything else (a bug) with the child's traceback. A stop that lands here
        leaves the child to :meth:`stop`."""
        if self._reaped:
            return None
        said = b""
        while chunk := os.read(self._read, 65536):  # (to the child's end, which closes its side)
            said += chunk
        _, status = os.waitpid(self.pid, 0)
        self._reaped = True
        os.close(self._read)
        code = os.waitstatus_to_exitcode(status)
        report = json.loads(said) if said else {}
        if code == 0:
            return report.get("result")
        if code == 128 + signal.SIGTERM:
            raise Terminated()
        if code == 128 + signal.SIGINT:
            raise KeyboardInterrupt
        kind = report.get("kind")
        if kind == "os":
            raise OSError(report["errno"], report["strerror"], report["filename"])
        if kind == "os-text":
            raise OSError(report["message"])
        if kind == "memory":
            raise MemoryError()
        if kind in ("failure", "config"):
            raise (ConfigError if kind == "config" else BoomHydraulicsError)(report["message"])
        if code < 0:  # killed by a signal of someone else's (the system out of memory: SIGKILL)
            name = signal.Signals(-code).name
            raise BoomHydraulicsError(f"a process this program forked for its work was killed by {name}")
        raise RuntimeError(f"a forked process ended with status {code}:\n{report.get('traceback', '')}")

    def stop(self) -> None:
        """End the child now, unless it is waited for already (this process failed or was
        stopped), and wait for it: it removes what it was writing, as a stopped program does."""
        if self._reaped:
            return
        before = signal.pthread_sigmask(signal.SIG_BLOCK, _STOPS)  # (a second stop does not cut this short)
        try:
            with suppress(OSError):  # first, so that a child writing its report is not held up
                os.close(self._read)
            with suppress(ProcessLookupError):
                os.kill(self.pid, signal.SIGTERM)
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, before)
        with suppress(ChildProcessError):
            os.waitpid(self.pid, 0)
        self._reaped = True


#: The signals that stop a program (run_main's).
_STOPS = frozenset({signal.SIGINT, signal.SIGTERM})


def can_fork() -> bool:
    """Whether :class:`Forked` may fork here: the platform forks, and no other Python thread is
    alive (one holding a lock at the fork would hold it in the child for ever; the native
    threads of numba's parallel kernels hold none)."""
    return hasattr(os, "fork") and threading.active_count() == 1


def _child(work: Callable[[], Any], read: int, write: int) -> NoReturn:
    """The forked child: ``work()``, then what it returned or how it failed as JSON on
    ``write``, and its exit status (0, 1, or 128 + the stop signal), without Python's exit (the
    parent's atexit handlers and buffers are the parent's). The first stop signal stops the
    work; from then on, and once the work is done, the child ignores them. An error that the
    code a stop landed in made of it (matplotlib's drawing, run_main) ends the child as the stop."""
    status = 1
    try:
        report: dict[str, Any] = {}
        os.close(read)
        _PENDING.clear()  # (the parent's stops are the parent's)
        for signum in _STOPS:
            signal.signal(signum, _stop_once)
        try:
            signal.pthread_sigmask(signal.SIG_UNBLOCK, _STOPS)  # (one that came since the fork lands here)
            report = {"result": work()}
            status = 0
        except Terminated:
            status = 128 + signal.SIGTERM
        except KeyboardInterrupt:
            status = 128 + signal.SIGINT
        except OSError as exc:
            report = (
                {"kind": "os", "errno": exc.errno, "strerror": exc.strerror, "filename": exc.filename}
                if exc.errno is not None
                else {"kind": "os-text", "message": str(exc)}
            )
        except MemoryError:
            report = {"kind": "memory"}
        except BoomHydraulicsError as exc:
            report = {"kind": "config" if isinstance(exc, ConfigError) else "failure", "message": str(exc)}
        except BaseException:
            report = {"kind": "bug", "traceback": traceback.format_exc()}
        finally:  # from here on a stop changes nothing: the child ends as decided
            _take_no_more_stops()
        if status == 1 and _PENDING:  # an error made of a stop: the stop
            status, report = 128 + _PENDING[-1], {}
        os.write(write, json.dumps(report, default=str).encode())
    finally:
        os._exit(status)


def _stop_once(signum: int, frame: Any) -> None:
    """A forked child's stop: the first signal raises (Ctrl-C's KeyboardInterrupt, SIGTERM's
    Terminated), the ones after it do nothing, so that none cuts short the clean-up of the first
    (the terminal's Ctrl-C reaches the child, and the parent's stop() sends SIGTERM after it)."""
    _take_no_more_stops()
    _PENDING.append(signum)
    raise Terminated() if signum == signal.SIGTERM else KeyboardInterrupt


def _take_no_more_stops() -> None:
    """In a forked child, the stop signals from here on do nothing. A handler that does nothing,
    not SIG_IGN: a signal that came just before is still handled by Python afterwards, and with
    SIG_IGN in place Python prints "OSError: Signal 15 ignored due to race condition" and a
    traceback (seen once in four Ctrl-Cs of a sweep while it plotted). The child leaves by
    os._exit, so Python's shutdown never puts the default action back."""
    for signum in _STOPS:
        signal.signal(signum, _no_stop)


def _no_stop(signum: int, frame: Any) -> None:
    """A stop signal a forked child takes once it is stopping or done: nothing."""

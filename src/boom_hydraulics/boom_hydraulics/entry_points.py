"""The programs' entry points (setup.py's console_scripts): each imports its program's module
behind a Ctrl-C guard, so that a Ctrl-C while the modules load (numpy, numba and rclpy: a
second or two, longer on a busy machine) ends in one line, as a Ctrl-C later does, and not
in a traceback. Once its module is loaded, the program's own handling takes over: the tools'
:func:`programs.run_main`, the node's :mod:`ros.process` (from rclpy's start on: the few
milliseconds before it, reading the parameters file, are in neither's hands).

This module is the top floor: it names the programs' modules as text and imports one of
them only when that program starts, so that starting one does not load the others.
"""

from __future__ import annotations

import gc
import importlib
import sys
from collections.abc import Callable

from .programs import NODE_STOPPED_WHILE_STARTING, ignore_stop_signals

#: A Ctrl-C while a tool's modules load: its line and exit status (as programs.run_main's for
#: a later Ctrl-C; nothing has been written yet).
INTERRUPTED = ("error: interrupted (Ctrl-C) while starting; nothing was written", 130)
#: The node's, as ros.process says it for a stop during its start (a node stopped by a signal exits 0).
NODE_STOPPED = (NODE_STOPPED_WHILE_STARTING, 0)


def guarded(module: str, prog: str, stopped: tuple[str, int] = INTERRUPTED) -> Callable[..., int | None]:
    """The entry point of ``prog``: ``module``'s ``main`` (given ``argv`` where a caller
    passes one, as the tests do), imported when called; a KeyboardInterrupt while it is
    imported prints ``prog: <line>`` and returns the status. Once the program is done (as a
    console script: no ``argv``), later stop signals are ignored."""

    def main(argv: list[str] | None = None) -> int | None:
        try:
            program = importlib.import_module(module).main
        except KeyboardInterrupt:
            ignore_stop_signals()  # (a second Ctrl-C, as a terminal and ros2 launch send together)
            line, status = stopped
            print(f"{prog}: {line}", file=sys.stderr, flush=True)
            return status
        if argv is not None:  # (called in a process that goes on: the tests)
            return program(argv)
        status = program()
        ignore_stop_signals()  # done, its line said: a second Ctrl-C in Python's shutdown changes nothing
        # What is alive now out of the garbage collector's walks: Python's shutdown walks the
        # heap in full collections, and numba's registries, loaded with a compiled kernel, are
        # some 120 000 objects (with a sweep's kernel loaded, the shutdown took 0.26 s walked,
        # 0.03 s frozen). What is then not collected goes with the process, as Python's own
        # shutdown leaves some.
        gc.freeze()
        return status

    main.__doc__ = f"``{prog}``: {module}.main, imported behind the Ctrl-C guard."
    return main


boom_sim = guarded("boom_hydraulics.ros.process", "boom_sim", NODE_STOPPED)
sim = guarded("boom_hydraulics.cli.sim", "boom-sim")
demo = guarded("boom_hydraulics.ros.demo", "boom-demo")
analyze = guarded("boom_hydraulics.cli.analyze", "boom-analyze")
study = guarded("boom_hydraulics.cli.study", "boom-study")
replay = guarded("boom_hydraulics.ros.replay", "boom-replay")
resim = guarded("boom_hydraulics.cli.resim", "boom-resim")
bag_recover = guarded("boom_hydraulics.cli.recover", "boom-bag-recover")
sweep = guarded("boom_hydraulics.cli.sweep", "boom-sweep")
calibrate = guarded("boom_hydraulics.cli.calibrate", "boom-calibrate")

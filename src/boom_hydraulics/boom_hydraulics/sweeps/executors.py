"""Where the batches of a sweep run: in this process, or on a Dask cluster.

Both offer ``map(fn, items)``, which yields ``(item, fn(item))`` as each finishes (in
any order), so the caller can store every result as soon as it exists. Leaving the
``with`` block (also by Ctrl-C) cancels what has not run yet.
"""

from __future__ import annotations

import collections
import contextlib
import logging
import os
import signal
import sys
import threading
import uuid
from collections.abc import Callable, Hashable, Iterable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any, TypeVar

from ..errors import BoomHydraulicsError, ConfigError
from ..programs import cancellable

Item = TypeVar("Item")

#: CPython's switch interval while batches run in threads, s. A batch whose kernel call returns
#: needs the GIL to go on (and to let the other batch's kernel start), which the other thread's
#: Python holds for up to the interval: 5 ms by default, at each of the hundred slices of a
#: 10 000-point sweep. The ten batches of that sweep, in two threads: 7.95-8.07 s at 0.5 ms
#: against 8.05-8.42 s at 5 ms (one after the other in one thread: 8.12-8.48 s; in turn, 3 rounds each).
SWITCH_INTERVAL_S = 0.0005


class _ShortSwitch:
    """The short switch interval while any map runs batches in threads; the interval from
    before the first of them once the last one ends (maps may overlap: interleaved, or in two
    threads)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._running = 0
        self._saved = 0.0

    def begin(self) -> None:
        with self._lock:
            if self._running == 0:
                self._saved = sys.getswitchinterval()
                sys.setswitchinterval(min(self._saved, SWITCH_INTERVAL_S))
            self._running += 1

    def end(self) -> None:
        with self._lock:
            self._running -= 1
            if self._running == 0:
                sys.setswitchinterval(self._saved)


_SHORT_SWITCH = _ShortSwitch()


@contextlib.contextmanager
def _environment(**values: str) -> Iterator[None]:
    """Set environment variables for what starts inside (worker processes inherit them)."""
    saved = {name: os.environ.get(name) for name in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def _close_quietly(clusters: Iterable[Any]) -> None:
    """Close clusters whose start was interrupted (this executor never got hold of them), so that
    distributed's exit hook does not try again and print a traceback about their half-made workers."""
    logging.getLogger("asyncio").setLevel(logging.CRITICAL)  # the workers' start tasks that were cut off
    for cluster in clusters:
        with contextlib.suppress(Exception):
            cluster.close(timeout=1)
        cluster.shutdown_on_close = False


class LocalExecutor:
    """The items in this process, in their order, ``threads`` at a time in threads of its own.

    A sweep's batch runs on every core in the compiled run kernel, which releases the GIL
    (jit.kernel) and runs one call at a time (solve.batch's kernel lock). Around its kernel, a
    batch spends Python on one core: its constants and start states before, its metrics after.
    With a second batch in a second thread, that Python runs while the other batch's kernel
    does, and the caller stores each result while the next ones run. The ten batches of a
    10 000-point sweep of 5 s lifts took 7.80-7.84 s so, against 7.95-8.07 s one after the
    other (2 cores, 3 rounds each). ``threads=1``: one item after the other in the calling thread.

    Before the first item of each ``kind`` (of the one kind, without ``kind``), ``load(item)``
    runs in the calling thread, once the items before it are delivered: what its calls need
    loaded (a sweep's run kernel: loaded from numba's cache in 0.3 s, or compiled in a minute),
    where a stop signal can interrupt it; a thread's compile would run to its end. That item
    then runs in a thread as the others do, beside the next one from the start: when it ran in
    the calling thread instead, alone, the Python before and after its kernel had no kernel
    beside it (0.05-0.1 s of a 10 000-point sweep). A stop signal (Ctrl-C, SIGTERM) lands in
    the calling thread. Once the caller stops taking results (by a stop, or an error of its
    own such as a full disk), the items running stop at the next slice of their run
    (programs.raise_pending), and their results are not kept.
    """

    description = "in this process"

    def __init__(
        self,
        threads: int = 2,
        load: Callable[[Any], object] | None = None,
        kind: Callable[[Any], Hashable] | None = None,
    ) -> None:
        if threads < 1:
            raise ValueError(f"threads must be >= 1, got {threads}")
        self.threads = threads
        self.load = load
        self.kind = kind

    def __enter__(self) -> LocalExecutor:
        return self

    def __exit__(self, *exc: object) -> None:
        return None

    def map(self, fn: Callable[[Item], Any], items: Iterable[Item]) -> Iterator[tuple[Item, Any]]:
        kinds: set[Hashable] = set()

        def first_of_its_kind(item: Item) -> bool:
            kind = self.kind(item) if self.kind is not None else None
            new = self.load is not None and kind not in kinds
            kinds.add(kind)
            return new

        if self.threads == 1:
            for item in items:
                if first_of_its_kind(item):
                    self.load(item)
                yield item, fn(item)
            return
        running: collections.deque[tuple[Item, Future]] = collections.deque()
        called_off = threading.Event()
        pool = ThreadPoolExecutor(self.threads, thread_name_prefix="boom-sweep-batch")
        _SHORT_SWITCH.begin()
        try:
            for item in items:
                if first_of_its_kind(item):  # its kernel loaded here, after the ones before it
                    yield from _delivered(running, keep=0)
                    self.load(item)
                running.append((item, pool.submit(cancellable, called_off, fn, item)))
                # the oldest is yielded once one more than the threads are in hand: while the
                # caller takes it, the next ones run
                yield from _delivered(running, keep=self.threads)
            yield from _delivered(running, keep=0)
        finally:  # done, or the caller stopped taking results: what still runs stops at its next slice
            called_off.set()
            try:
                pool.shutdown(wait=True, cancel_futures=True)
            finally:  # (a second stop may cut the wait short)
                _SHORT_SWITCH.end()


def _delivered(running: collections.deque[tuple[Item, Future]], keep: int) -> Iterator[tuple[Item, Any]]:
    """The oldest of ``running`` with their results, in order, until ``keep`` are left."""
    while len(running) > keep:
        first, future = running.popleft()
        yield first, future.result()


class DaskExecutor:
    """Items as tasks on a Dask cluster: the scheduler at ``scheduler``
    (``tcp://host:8786``), or a local cluster of ``workers`` processes started here.

    Workers need boom_hydraulics importable (the same installation as here).
    """

    def __init__(self, scheduler: str | None = None, workers: int | None = None, connect_s: float = 10.0) -> None:
        if (scheduler is None) == (workers is None):
            raise ValueError("give a scheduler address or a number of local workers")
        if workers is not None and workers < 1:
            raise ConfigError(f"--workers must be >= 1, got {workers}")
        if not connect_s > 0:
            raise ConfigError(f"--scheduler-timeout must be > 0 s, got {connect_s}")
        self.scheduler, self.workers, self.connect_s = scheduler, workers, connect_s
        self.cluster: Any = None
        self.client: Any = None
        self.description = (
            f"on the Dask scheduler at {scheduler}" if scheduler else f"on a local Dask cluster of {workers} processes"
        )

    def __enter__(self) -> DaskExecutor:
        from distributed import Client, LocalCluster
        from distributed.deploy.spec import SpecCluster

        before = set(SpecCluster._instances)
        try:
            if self.scheduler is not None:
                self.client = Client(self.scheduler, timeout=f"{self.connect_s}s")
            else:
                # each worker process runs the compiled kernel on its share of the cores
                threads = max(1, (os.cpu_count() or 1) // self.workers)
                with _environment(NUMBA_NUM_THREADS=str(threads)):
                    self.cluster = LocalCluster(
                        n_workers=self.workers, threads_per_worker=1, processes=True, dashboard_address=None
                    )
                self.client = Client(self.cluster)
        except (OSError, TimeoutError, ValueError) as exc:
            self.__exit__()
            where = f"the Dask scheduler at {self.scheduler}" if self.scheduler else "a local Dask cluster"
            raise ConfigError(
                f"cannot reach {where}: {exc}; start one with 'dask scheduler' and 'dask worker ADDRESS', "
                "or leave out --scheduler to run in this process"
            ) from None
        except BaseException:  # Ctrl-C while the cluster starts: end what had started, quietly
            self.__exit__()
            _close_quietly(set(SpecCluster._instances) - before)
            raise
        return self

    def __exit__(self, kind: type | None = None, *exc: object) -> None:
        if kind is not None and issubclass(kind, KeyboardInterrupt):
            self._stop_now()
        if self.client is not None:
            self.client.close()
        if self.cluster is not None:
            self.cluster.close()
        self.client = self.cluster = None

    def _stop_now(self) -> None:
        """On Ctrl-C or SIGTERM: kill the local workers' processes at once. A task in the run kernel
        cannot be cancelled, and the cluster would wait for it (4 s) before killing them itself;
        their results are not wanted, and what they computed is not ours to store. Quiet, too:
        the cluster's warnings about cancelled tasks are no news to the user."""
        logging.getLogger("distributed").setLevel(logging.CRITICAL)
        logging.getLogger("asyncio").setLevel(logging.CRITICAL)
        if self.cluster is None:
            return  # a remote cluster's workers are not ours; cancelling the tasks is all we may do
        for nanny in list(getattr(self.cluster, "workers", {}).values()):
            with contextlib.suppress(Exception):
                if nanny.pid:
                    os.kill(nanny.pid, signal.SIGKILL)

    def map(self, fn: Callable[[Item], Any], items: Iterable[Item]) -> Iterator[tuple[Item, Any]]:
        from distributed import as_completed

        run = uuid.uuid4().hex[:8]
        futures = {
            self.client.submit(fn, item, key=f"boom-sweep-{run}-{n}", pure=False): item for n, item in enumerate(items)
        }
        try:
            for future in as_completed(futures):
                try:
                    result = future.result()
                except Exception as exc:  # raised on a worker: name it, keep what is stored
                    raise BoomHydraulicsError(
                        f"a task failed {self.description}: {type(exc).__name__}: {exc} "
                        "(workers need boom_hydraulics installed, the same version as here)"
                    ) from exc
                yield futures[future], result
        finally:
            self.client.cancel(list(futures))

"""Background reads of a chunked hierarchy's cells for the viewer's still frames.

A chunked hierarchy (:class:`~surfsplat.hierarchy.chunked.ChunkedHierarchy`) reads the cells a view
needs from disk when it is cut; that can take seconds, and the frame loop must not wait for it.
:class:`CellStreamer` runs the cuts in one worker thread (:mod:`concurrent.futures`): the main
thread asks for a view's cut without blocking, keeps drawing meanwhile and uploads the splats when
they have arrived (GL calls stay on the main thread). Every access to the model's cells goes
through that one worker, so its LRU cache (not thread-safe) is only ever touched by one thread, and
cuts run one after the other: a cell two views need is read once and then found in the cache.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable
from concurrent.futures import Future, ThreadPoolExecutor

#: How often (seconds) the frame loop looks whether a pending cut has arrived.
STREAM_POLL_S = 0.02


class CellStreamer:
    """Runs view cuts of a chunked hierarchy in one background thread, newest view first.

    Each cut is known by a key (the view: camera, tolerance, culling, budget); :meth:`poll`
    returns its result once it is there, :meth:`result` waits for it. Asking for a new key
    cancels a cut that has not started yet (a running one finishes: its cells stay cached).
    """

    def __init__(self):
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="surfsplat-cells")
        self._key: Hashable | None = None
        self._future: Future | None = None
        self.submitted = 0

    def _submit(self, key: Hashable, cut: Callable[[], object]) -> Future:
        if self._key != key or self._future is None or self._future.cancelled():
            if self._future is not None:
                self._future.cancel()   # not started yet: dropped; running: finishes, result unused
            self._key, self._future = key, self._executor.submit(cut)
            self.submitted += 1
        return self._future

    def poll(self, key: Hashable, cut: Callable[[], object]):
        """The result of ``cut()`` for ``key`` if it has finished, else None (it is started in the
        background when ``key`` is new; never blocks). Errors raised by ``cut`` are raised here."""
        future = self._submit(key, cut)
        return future.result() if future.done() else None

    def result(self, key: Hashable, cut: Callable[[], object]):
        """The result of ``cut()`` for ``key``, waiting for the background thread if needed."""
        return self._submit(key, cut).result()

    @property
    def pending(self) -> bool:
        """Whether a cut is being read (or waits to be)."""
        return self._future is not None and not self._future.done()

    def close(self) -> None:
        """Drop queued cuts and wait for the running one to finish (at most one cut's reads)."""
        self._executor.shutdown(wait=True, cancel_futures=True)

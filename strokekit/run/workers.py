"""Where frames are rendered: this process and threads of it (they share its scene, BVH and
renderer), or this process and a spawn-started process pool, or a dask.distributed cluster
(`make_executor` -> `Workers`). Each worker process loads the scene and builds its BVH once and
keeps its renderer."""

from __future__ import annotations

import threading
from collections import deque
from concurrent.futures import FIRST_COMPLETED, Executor, ProcessPoolExecutor, ThreadPoolExecutor, wait
from dataclasses import dataclass
from typing import Callable

from strokekit.errors import InputError
from strokekit.extras import need
from strokekit.lines.renderer import LineRenderer
from strokekit.options import LineOptions
from strokekit.scene.load import Scene, load_scene

# --- worker side -----------------------------------------------------------------------------------

_WORKER_CACHE: dict = {}
#: Held while a renderer is looked up or built: a pool's threads share this process's cache.
_CACHE_LOCK = threading.Lock()


@dataclass(frozen=True)
class SceneRef:
    """A run's scene as its tasks name it: the file, the content hash the run started with ("":
    any) and the line options its renderer is built with."""

    path: str
    content_hash: str
    lines: LineOptions

    def renderer(self) -> LineRenderer:
        """This process's renderer of the scene, loaded and its BVH built once per process."""
        with _CACHE_LOCK:
            return self._renderer()

    def _renderer(self) -> LineRenderer:
        key = (self.path, self.lines)
        r = _WORKER_CACHE.get(key)
        if r is not None and self.content_hash and r.scene.content_hash != self.content_hash:
            r = None  # kept from an earlier run (a dask worker lives on): the file has changed since
        if r is None:
            _WORKER_CACHE.clear()
            r = LineRenderer(load_scene(self.path), self.lines)
            _WORKER_CACHE[key] = r
        if self.content_hash and r.scene.content_hash != self.content_hash:
            raise InputError("scene file changed during the run", self.path)
        return r

    def keep(self, scene: Scene) -> None:
        """Make `scene` (this file, already loaded here) this process's renderer of it."""
        with _CACHE_LOCK:
            r = _WORKER_CACHE.get((self.path, self.lines))
            if r is None or r.scene.content_hash != scene.content_hash:
                _WORKER_CACHE.clear()
                _WORKER_CACHE[(self.path, self.lines)] = LineRenderer(scene, self.lines)


def _warm_worker(scene: SceneRef, started) -> None:
    """Pool initializer: import, load the scene and build its BVH while the main process loads
    its own copy, instead of after it, then count this worker in `started` (a shared integer).
    Errors are left to the frame tasks to report (an initializer that raises would break the
    whole pool). (The raster kernels load in the worker's first raster frame: loading them here
    would only move the same work earlier; a worker gets frames as soon as it has started.)"""
    try:
        scene.renderer()
    except Exception:
        with _CACHE_LOCK:
            _WORKER_CACHE.clear()
    with started.get_lock():
        started.value += 1


def _noop() -> None:
    return None


# --- executors ---------------------------------------------------------------------------------------

class _NoPool:
    """The `started` count of a run without pool workers: none will ever start."""

    value = 0


@dataclass(frozen=True)
class _Threads:
    """The `started` count of a thread pool: its threads share this process's scene and BVH,
    so they are ready at once."""

    value: int


@dataclass
class Workers:
    """Where frame tasks run. `executor` takes them; beside a local pool (`started` set: --workers
    N is this process and N - 1 pool workers) this process runs tasks too (`main_helps`)."""

    executor: Executor | None  # None: this process runs every task (main_helps, no pool)
    close: Callable[[], None]  # may be called more than once (an interrupted run closes them itself)
    #: Pool workers that have finished starting (imports, scene, BVH): a shared integer (always
    #: 0 when this process is the only one), or None when this process does not render (dask).
    started: object | None = None
    #: A dask cluster's `client.run`: call a function on every worker -> {worker address: result}.
    on_each: Callable[[Callable], dict] | None = None

    @property
    def main_helps(self) -> bool:
        return self.started is not None

    def _capacity(self) -> int:
        return 2 * self.started.value if self.main_helps else 1 << 30

    def map(self, tasks, handle: Callable[[object], bool]) -> None:
        """Run every task of `tasks` (a picklable callable without arguments), calling
        `handle(result)` in this process as each finishes (in any order); `handle` returning False
        stops the rest. `tasks` may be a deque that `handle` adds to while the map runs
        (appendleft: next in line): those run too.

        With main_helps, each pool worker that has started gets at most two tasks queued and
        this process runs the others one by one, so frames get done while the workers are
        still starting (a spawned worker needs seconds of imports and scene loading; a short
        run ends before they are up) and no worker idles."""
        if self.main_helps and self.executor is not None:
            return self._map_helping(tasks, handle)
        pending = tasks if isinstance(tasks, deque) else deque(tasks)
        running: set = set()
        go = True

        def collect(futs) -> bool:
            for fut in futs:
                running.discard(fut)
                if not handle(fut.result()):
                    return False
            return True

        while go and (pending or running):
            while pending and len(running) < self._capacity():
                running.add(self.executor.submit(pending.popleft()))
            if self.main_helps and pending:
                go = handle(pending.popleft()()) and collect([f for f in running if f.done()])
            elif running:
                done, _ = wait(running, return_when=FIRST_COMPLETED)
                go = collect(done)
        _stop(running, handle)

    def _map_helping(self, tasks, handle: Callable[[object], bool]) -> None:
        """map() beside a local pool that this process helps. A worker's next task is sent the
        moment its result arrives (by the pool's result thread, in a done-callback), not when
        this process has finished the frame it is rendering and handled the results (with
        tracking, the tracking pass too): so a worker does not starve while this process renders
        and tracks.

        A worker gets a second task queued (to cover the round trip) only while more than two
        tasks per worker remain; near the end it gets one at a time and this process takes the
        rest, so a worker is not left with a queued frame while this process has nothing to do.
        Results are still handled here, in this thread."""

        pending = tasks if isinstance(tasks, deque) else deque(tasks)
        lock = threading.RLock()
        running: set = set()  # submitted, result not yet handled here
        # busy: submitted and not finished; feeding: feed() is running (in the thread holding
        # `lock`: a future already done when its callback is added calls it right there).
        state = {"stop": False, "busy": 0, "feeding": False}

        def capacity() -> int:
            # Two tasks per started worker; one each once no more than two per worker remain for
            # the workers and this process to share.
            n = self.started.value
            return 2 * n if len(pending) > 2 * n else n

        def feed() -> None:
            """Top the pool up from `pending` (holding `lock`)."""
            state["feeding"] = True
            try:
                while not state["stop"] and pending and state["busy"] < capacity():
                    item = pending.popleft()
                    try:
                        fut = self.executor.submit(item)
                    except Exception:
                        pending.appendleft(item)  # the pool is closed or broken: this thread runs it
                        state["stop"] = True
                        return
                    state["busy"] += 1
                    running.add(fut)
                    fut.add_done_callback(finished)
            finally:
                state["feeding"] = False

        def finished(fut) -> None:  # in the pool's result thread (or in feed(), if already done)
            if fut.cancelled() or fut.exception() is not None:
                # A dead worker (the tasks catch their own errors): the pool is broken. Python >= 3.12
                # completes the futures while holding the executor's _shutdown_lock, which submit()
                # needs (and `lock` may be held by a feed() waiting for it): feed nothing, take no lock.
                state["stop"] = True
                return
            with lock:
                state["busy"] -= 1
                if not state["feeding"]:
                    feed()

        def handled(r) -> bool:
            if handle(r):
                return True
            with lock:
                state["stop"] = True  # fail-fast: no more tasks go to the pool
            return False

        def collect() -> bool:
            with lock:
                done = [f for f in running if f.done()]
            for f in done:
                with lock:
                    running.discard(f)
                if not handled(f.result()):
                    return False
            return True

        try:
            go = True
            while go:
                with lock:
                    feed()
                    item = pending.popleft() if pending else None
                    waiting = list(running)
                if item is not None:
                    go = handled(item()) and collect()
                elif waiting:
                    wait(waiting, return_when=FIRST_COMPLETED)
                    go = collect()
                else:
                    break
        finally:
            with lock:
                state["stop"] = True
                left = list(running)
        _stop(left, handle)


def _stop(running, handle: Callable[[object], bool]) -> None:
    """Stopped early (or done): tasks already running finish (they may be writing files) and
    their results are handled (the files they wrote are reported); queued ones are dropped."""
    for fut in running:
        fut.cancel()
    wait(running)
    for fut in running:
        if not fut.cancelled() and fut.exception() is None:
            handle(fut.result())


def make_executor(workers: int, scheduler: str | None, warm: SceneRef, kind: str = "threads") -> Workers:
    """Where the run's tasks go. `scheduler` 'tcp://host:port': a dask.distributed cluster.
    Otherwise `workers` on this machine: this process, plus workers - 1 threads of it (`kind`
    "threads": they share its scene and BVH) or a spawn-started pool of workers - 1 processes
    ("processes", started now; each loads the `warm` scene and builds its BVH right away)."""
    if scheduler:
        need("distributed", "--scheduler")
        from distributed import Client

        try:
            client = Client(scheduler, timeout=10)
        except Exception as e:
            raise InputError(f"cannot reach the dask scheduler at {scheduler} ({e})") from None
        ex = client.get_executor(pure=False)
        return Workers(ex, _once(client.close), on_each=client.run)
    if workers <= 1:
        # This process does every task, one by one, handling each result before the next task.
        return Workers(None, lambda: None, started=_NoPool())
    if kind == "threads":
        tex = ThreadPoolExecutor(max_workers=workers - 1, thread_name_prefix="strokekit-frames")
        # (close: the frames a thread is drawing finish; a frame is a fraction of a second)
        return Workers(tex, _once(lambda: tex.shutdown(wait=True, cancel_futures=True)),
                       started=_Threads(workers - 1))
    import multiprocessing as mp
    import signal

    ctx = mp.get_context("spawn")
    started = ctx.Value("i", 0)
    ex = ProcessPoolExecutor(max_workers=workers - 1, mp_context=ctx, initializer=_warm_worker,
                             initargs=(warm, started))
    # A pool spawns its workers on demand: ask for all of them now. They inherit an ignored
    # SIGINT, so Ctrl-C reaches this process alone (one "aborted" line, no traceback from a
    # worker interrupted in its imports) and close() ends them.
    try:
        old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    except ValueError:  # not the main thread: signals are not ours to change
        old = None
    try:
        for _ in range(workers - 1):
            ex.submit(_noop)
    finally:
        if old is not None:
            signal.signal(signal.SIGINT, old)

    def close() -> None:
        # Our tasks have all finished by now (Workers.map waits for running ones; an interrupt
        # or error ends the run anyway); a worker may still be in its initializer, as a short
        # run can end before the pool is up. Waiting would add its whole start-up to the run, so
        # idle or starting workers are stopped instead (ProcessPoolExecutor has no public way).
        # The pool's manager thread is joined here: shutdown forgets it too, and one still closing
        # its pipes at interpreter exit races the exit hook's wake-up ("Bad file descriptor").
        procs = list((getattr(ex, "_processes", None) or {}).values())  # shutdown forgets them
        manager, results = getattr(ex, "_executor_manager_thread", None), getattr(ex, "_result_queue", None)
        ex.shutdown(wait=False, cancel_futures=True)
        for proc in procs:
            proc.terminate()
        if manager is not None:
            manager.join()
        if results is not None:
            results.close()

    return Workers(ex, _once(close), started=started)


def _once(fn: Callable[[], None]) -> Callable[[], None]:
    done = []

    def call_once() -> None:
        if not done:
            done.append(True)
            fn()

    return call_once

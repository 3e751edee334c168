"""A per-sample trace of the stream process's deadline loop, for the benchmarks (off unless asked for).

A gap in the commands a subscriber receives is either the stream's own (the
loop woke late, or ``publish`` itself blocked) or the transport's / the
receiver's (the sample left on time and arrived late, or not at all).  Only
the sender can tell: with the environment variable :data:`TRACE_ENV` set to a
file name, the stream process records for every sample sent its deadline, the
instant the loop woke, the system time just before ``publish`` and the
instants ``publish`` returned and the step ended (after the slack work: a
garbage collection), and writes them to that file (``.npy``, one row per
sample, columns :data:`COLUMNS`) when its stream ends.  ``bench/storm.py``
sets it and classifies every gap with it.  Memory is allocated once
(:data:`TRACE_ROWS` rows, 8 bytes per column); later samples are not recorded.

Around the deadline sleep (:meth:`StreamTrace.sleep`, the stream's injected
``sleep``) it also records which CPU the thread slept on and woke on
(``sched_getcpu``), and what happened to the thread inside the sleep call: its
voluntary context switches (1: the sleep itself; more: it blocked again after
the timer woke it -- waiting for the interpreter lock or another lock before
the sleep call could return), involuntary ones (preempted), the times it was
switched in, its run-queue wait and CPU time, and its page faults.  A late
wake with one switch, no run-queue wait and no fault was late before the
thread could run at all: the timer or the (virtual) CPU.  The request loop of
the stream process (the only other Python thread that runs while it streams)
records each request it handles (:meth:`StreamTrace.request`), written beside
the trace (:func:`requests_path`): a late wake during one is a candidate for
the interpreter lock.
"""

from __future__ import annotations

import ctypes
import os
import resource
import threading
import time

import numpy as np

from .heap import resident_zeros

#: Environment variable naming the trace file (unset: no trace).
TRACE_ENV = "FLEXMOTION_STREAM_TRACE"
#: Rows kept (20 min at 1 kHz).
TRACE_ROWS = 1_200_000
#: Columns: the sample index, its deadline, the wake-up after the sleep, the system time before publishing (ns),
#: the instant publish returned, the start of the slack work, the end of the matched-count refresh in it, the
#: generation collected in it (-1: none), the end of the step, and the stream thread's run delay (its time waiting
#: on a run queue, cumulative, ns; ``/proc/thread-self/schedstat``; 0 where not Linux) before and after publishing.
#: Then, around the deadline sleep (:meth:`StreamTrace.sleep`; 0 / -1 where the sample was due before the sleep):
#: the instant the sleep was called, the CPU the thread slept on and the one it woke on (-1: unknown), and inside
#: the sleep call: the voluntary and involuntary context switches, the times the thread was switched in, its
#: run-queue wait and CPU time (ns), and its page faults (minor + major); and the page faults from the wake-up to
#: the end of the step.  Last, around ``publish`` (:meth:`StreamTrace.before_publish`, :meth:`StreamTrace.published`):
#: the CPU the step ran on before publishing (whether or not it slept: the step's start) and after, and the
#: voluntary context switches (a block: a lock, DDS's or the interpreter's) and involuntary ones (preempted)
#: inside the call.  Monotonic columns in s.
COLUMNS = (
    "k",
    "deadline",
    "woke",
    "publish_ns",
    "published",
    "slack_start",
    "matched_end",
    "collected",
    "step_end",
    "run_delay_before",
    "run_delay_after",
    "slept_at",
    "cpu_slept",
    "cpu_woke",
    "sleep_switches",
    "sleep_preempted",
    "sleep_runs",
    "sleep_run_delay",
    "sleep_cpu_ns",
    "sleep_faults",
    "step_faults",
    "cpu_step",
    "cpu_published",
    "publish_switches",
    "publish_preempted",
)
(
    K,
    DEADLINE,
    WOKE,
    PUBLISH_NS,
    PUBLISHED,
    SLACK_START,
    MATCHED_END,
    COLLECTED,
    STEP_END,
    RUN_DELAY_BEFORE,
    RUN_DELAY_AFTER,
    SLEPT_AT,
    CPU_SLEPT,
    CPU_WOKE,
    SLEEP_SWITCHES,
    SLEEP_PREEMPTED,
    SLEEP_RUNS,
    SLEEP_RUN_DELAY,
    SLEEP_CPU_NS,
    SLEEP_FAULTS,
    STEP_FAULTS,
    CPU_STEP,
    CPU_PUBLISHED,
    PUBLISH_SWITCHES,
    PUBLISH_PREEMPTED,
) = range(len(COLUMNS))
#: Columns of the request loop's record (:func:`requests_path`): the request (:data:`REQUEST_OPS` index), the
#: instants its handling started and ended (monotonic s).
REQUEST_COLUMNS = ("op", "start", "end")
#: The requests the record names (index: the ``op`` column; -1: another).
REQUEST_OPS = ("configure", "start", "stop", "start_now", "splice", "hold_when_idle")
#: Requests kept.
REQUEST_ROWS = 200_000
#: No sleep was called for the sample (it was due already): its sleep columns.
NO_SLEEP = (0.0, -1.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


def requests_path(path: str) -> str:
    """Where the request loop's record of trace file ``path`` goes (``x.npy`` -> ``x.requests.npy``)."""
    return (path[:-4] if path.endswith(".npy") else path) + ".requests.npy"


def _cpu_reader():
    """``sched_getcpu`` (libc, through ctypes; about 0.1 us), or a function returning -1 where there is none."""
    try:
        fn = ctypes.CDLL(None, use_errno=True).sched_getcpu
        fn.restype, fn.argtypes = ctypes.c_int, []
        fn()
        return fn
    except (OSError, AttributeError):
        return lambda: -1


def _faults() -> tuple[int, int, int]:
    """The calling thread's (voluntary, involuntary) context switches and page faults so far."""
    r = resource.getrusage(resource.RUSAGE_THREAD)
    return r.ru_nvcsw, r.ru_nivcsw, r.ru_minflt + r.ru_majflt


class StreamTrace:
    """Rows of :data:`COLUMNS`, filled by the stream thread (:meth:`published`, :meth:`step_done`).

    Parameters
    ----------
    path : str
        Where :meth:`save` writes the rows (``.npy``).
    rows : int
        Capacity (samples).
    """

    def __init__(self, path: str, rows: int = TRACE_ROWS) -> None:
        self.path = path
        # resident now: a first touch in the deadline loop faults a 2 MiB huge page per 12,483 rows (4 ms late)
        self._rows = resident_zeros((int(rows), len(COLUMNS)))
        self._n = 0
        self._publish_ns = 0
        self._published = 0.0
        self._slack = (0.0, 0.0, -1.0)
        self._delay = (0.0, 0.0)
        self._before: tuple[float, int, int, int] = (0.0, -1, 0, 0)  # run delay, CPU, switches before publish
        self._around: tuple[float, ...] = (-1.0, -1.0, 0.0, 0.0)
        self._schedstat: tuple[int, int] | None = None  # (thread id, its schedstat fd)
        self._sleep: tuple[float, ...] = NO_SLEEP
        self._wake_faults = -1
        self._cpu = _cpu_reader()
        self._requests = resident_zeros((REQUEST_ROWS, len(REQUEST_COLUMNS)))
        self._n_requests = 0
        self._requests_lock = threading.Lock()

    @classmethod
    def from_environment(cls) -> StreamTrace | None:
        """A trace if :data:`TRACE_ENV` names a file, else None."""
        path = os.environ.get(TRACE_ENV, "")
        return cls(path) if path else None

    def run_delay(self) -> float:
        """The calling thread's cumulative run-queue wait (ns; 0 if unknown): read before and after publishing."""
        return self.schedstat()[1]

    def schedstat(self) -> tuple[float, float, float]:
        """The calling thread's CPU time and run-queue wait (ns) and times switched in (0s if unknown)."""
        try:
            tid = threading.get_native_id()
            if self._schedstat is None or self._schedstat[0] != tid:  # a restarted stream runs a new thread
                if self._schedstat is not None:
                    os.close(self._schedstat[1])
                self._schedstat = (tid, os.open("/proc/thread-self/schedstat", os.O_RDONLY))
            on_cpu, delay, runs = os.pread(self._schedstat[1], 64, 0).split()[:3]
            return float(on_cpu), float(delay), float(runs)
        except (OSError, ValueError):
            return 0.0, 0.0, 0.0

    def sleep(self, seconds: float) -> None:
        """``time.sleep(seconds)``, with the thread's CPU and scheduling read before and after (the stream's sleep)."""
        cpu0 = self._cpu()
        vol0, inv0, faults0 = _faults()
        _, delay0, runs0 = self.schedstat()
        on_cpu0 = time.thread_time_ns()  # exact (the kernel's schedstat CPU time is charged at switches and ticks)
        slept_at = time.monotonic()
        time.sleep(seconds)
        # the first Python instruction after the sleep call returned (the interpreter lock taken again)
        on_cpu1 = time.thread_time_ns()
        cpu1 = self._cpu()
        _, delay1, runs1 = self.schedstat()
        vol1, inv1, faults1 = _faults()
        self._wake_faults = faults1
        self._sleep = (
            slept_at,
            float(cpu0),
            float(cpu1),
            float(vol1 - vol0),
            float(inv1 - inv0),
            runs1 - runs0,
            delay1 - delay0,
            float(on_cpu1 - on_cpu0),
            float(faults1 - faults0),
        )

    def request(self, op: str, start: float, end: float) -> None:
        """The request loop handled ``op`` from ``start`` to ``end`` (monotonic s; any thread)."""
        with self._requests_lock:
            n = self._n_requests
            if n < len(self._requests):
                self._requests[n] = (REQUEST_OPS.index(op) if op in REQUEST_OPS else -1, start, end)
                self._n_requests = n + 1

    def before_publish(self) -> None:
        """Just before ``publish``: the run delay, the CPU and the context switches so far (:meth:`published`)."""
        vol, inv, _ = _faults()
        self._before = (self.run_delay(), self._cpu(), vol, inv)

    def published(self, publish_ns: int) -> None:
        """Publish returned (``publish_ns``: the system time just before it, ns); :meth:`before_publish` before it."""
        self._publish_ns = publish_ns
        self._published = time.monotonic()
        cpu = self._cpu()
        vol, inv, _ = _faults()
        delay, cpu0, vol0, inv0 = self._before
        self._delay = (delay, self.run_delay())
        self._around = (float(cpu0), float(cpu), float(vol - vol0), float(inv - inv0))

    def slack(self, start: float, matched_end: float, collected: int) -> None:
        """The slack work after a sample: its start, the matched count's end (monotonic s), the generation collected."""
        self._slack = (start, matched_end, float(collected))

    def step_done(self, k: int, deadline: float, woke: float) -> None:
        """The step that sent sample ``k`` ended (deadline and wake-up on the monotonic clock, s)."""
        n = self._n
        if n < len(self._rows):
            end = time.monotonic()
            faults = _faults()[2] - self._wake_faults if self._wake_faults >= 0 else 0
            self._rows[n] = (
                k,
                deadline,
                woke,
                float(self._publish_ns),
                self._published,
                *self._slack,
                end,
                *self._delay,
                *self._sleep,
                float(faults),
                *self._around,
            )
            self._n = n + 1
        self._slack = (0.0, 0.0, -1.0)
        self._sleep = NO_SLEEP
        self._wake_faults = -1
        self._around = (-1.0, -1.0, 0.0, 0.0)

    def save(self) -> None:
        """Write the rows recorded so far (appending to what an earlier configuration of the child wrote)."""
        rows = self._rows[: self._n]
        if os.path.exists(self.path):
            try:
                rows = np.concatenate([np.load(self.path), rows])
            except (OSError, ValueError):
                pass
        np.save(self.path, rows)
        self._n = 0
        with self._requests_lock:
            requests, self._n_requests = self._requests[: self._n_requests].copy(), 0
        path = requests_path(self.path)
        if os.path.exists(path):
            try:
                requests = np.concatenate([np.load(path), requests])
            except (OSError, ValueError):
                pass
        np.save(path, requests)


__all__ = ["COLUMNS", "REQUEST_COLUMNS", "REQUEST_OPS", "TRACE_ENV", "TRACE_ROWS", "StreamTrace", "requests_path"]

"""A live stream's plumbing, without ROS: queues between a subscriber and its workers, and the
stream's figures.

:class:`FrameQueue` (pcd_save) is a bounded FIFO that never blocks the receiving thread: when full, the
oldest frame is discarded; :class:`DropCounter` counts the frames lost on the way (sequence gaps) and
those discarded. :class:`NewestFrame` (can_tracker) hands a worker only the newest frame, counting those
replaced as skipped; :class:`StreamStats` gives the rates, skipped frames, latency percentiles and compute
per frame (in all and by stage) that can_tracker reports on /diagnostics. Times in seconds.
"""
from __future__ import annotations

import collections
import threading
import time
from typing import Deque, Dict, Optional

import numpy as np


class DropCounter:
    """Counts frames lost before pcd_save saw them (sequence gaps) and frames it discarded.

    Sequence numbers are tracked per publisher (rospy numbers each publisher's messages from 1),
    so two publishers on one topic are not mistaken for gaps. A sequence number that goes back is
    a restarted publisher (or a looping bag): it starts a new count, nothing is lost.
    """

    def __init__(self):
        self.received = 0
        self.seq_gaps = 0
        self.queue_discards = 0
        self.restarts = 0
        self._last_seq: Dict[str, int] = {}

    def observe(self, seq: int, publisher: str = "") -> int:
        """Records a received frame; returns the frames missing just before it."""
        self.received += 1
        last = self._last_seq.get(publisher)
        self._last_seq[publisher] = seq
        if last is None:
            return 0
        if seq <= last:
            self.restarts += 1
            return 0
        gap = seq - last - 1
        self.seq_gaps += gap
        return gap

    def discarded(self, n: int = 1) -> None:
        self.queue_discards += n

    @property
    def dropped(self) -> int:
        return self.seq_gaps + self.queue_discards

    def summary(self) -> str:
        return (f"dropped {self.dropped} (sequence gaps {self.seq_gaps}, queue discards {self.queue_discards})"
                + (f", {self.restarts} sequence restarts" if self.restarts else ""))


class FrameQueue:
    """A bounded FIFO that never blocks the producer: when full, the oldest item is discarded.

    ``put`` returns the number of items discarded (0 or 1). ``get`` blocks until an item arrives,
    ``close`` is called (then returns None) or ``timeout`` passes (returns None).
    """

    def __init__(self, maxsize: int):
        if maxsize < 1:
            raise ValueError(f"maxsize must be >= 1, got {maxsize}")
        self._items: Deque = collections.deque()
        self._maxsize = maxsize
        self._cond = threading.Condition()
        self._closed = False

    def put(self, item) -> int:
        with self._cond:
            discarded = 0
            if len(self._items) >= self._maxsize:
                self._items.popleft()
                discarded = 1
            self._items.append(item)
            self._cond.notify()
            return discarded

    def get(self, timeout: Optional[float] = None):
        with self._cond:
            deadline = None if timeout is None else time.monotonic() + timeout
            while not self._items and not self._closed:
                remaining = None if deadline is None else deadline - time.monotonic()
                if remaining is not None and remaining <= 0:
                    return None
                self._cond.wait(remaining)
            return self._items.popleft() if self._items else None

    def close(self) -> int:
        """Wakes every getter; returns the number of items left unwritten (they are dropped)."""
        with self._cond:
            self._closed = True
            left = len(self._items)
            self._items.clear()
            self._cond.notify_all()
            return left

    def __len__(self) -> int:
        with self._cond:
            return len(self._items)


class NewestFrame:
    """A one-item mailbox between a subscriber callback and a worker thread.

    put() stores an item, replacing (and counting as skipped) one the worker has not taken;
    take() waits for an item and removes it; close() wakes the worker for good (take returns None).
    """

    def __init__(self):
        self._condition = threading.Condition()
        self._item = None
        self._closed = False
        self.skipped = 0  # items replaced before the worker took them

    def put(self, item):
        """Stores item as the newest; returns True when it replaced one not taken (a skipped frame)."""
        with self._condition:
            replaced = self._item is not None
            if replaced:
                self.skipped += 1
            self._item = item
            self._condition.notify()
            return replaced

    def take(self, timeout=None):
        """The newest item, waiting up to timeout (s; None: for ever); None when closed or timed out."""
        with self._condition:
            self._condition.wait_for(lambda: self._item is not None or self._closed, timeout)
            if self._closed:
                return None
            item, self._item = self._item, None
            return item

    def close(self):
        """Wakes the worker: every take from now on returns None at once."""
        with self._condition:
            self._closed = True
            self._item = None
            self._condition.notify_all()

    @property
    def closed(self):
        return self._closed


def percentiles(values, qs=(50, 90, 99)):
    """{q: the q-th percentile of values} (NaN for none)."""
    values = np.asarray(list(values), dtype=float)
    if values.size == 0:
        return {q: float("nan") for q in qs}
    return {q: float(v) for q, v in zip(qs, np.percentile(values, qs))}


class StreamStats:
    """Figures of a stream over the last `window` seconds (arrival and processing times are the
    caller's clock, s): input and processed rates, latency (output time minus the input's stamp),
    compute (s per processed frame) and the seconds of each named stage (on the frames that ran
    it); plus counts since the start. Not thread-safe: callers hold their lock."""

    def __init__(self, window=5.0):
        if not window > 0:
            raise ValueError(f"the window must be > 0 s, got {window}")
        self.window = float(window)
        self._arrivals = collections.deque()
        self._processed = collections.deque()  # (time, latency, compute)
        self._stages = {}  # name: deque of (time, seconds)
        self.received = 0
        self.processed = 0
        self.dropped = 0  # frames refused (bad input, no transform)
        self.last_arrival = None

    def _trim(self, now):
        start = now - self.window
        while self._arrivals and self._arrivals[0] < start:
            self._arrivals.popleft()
        while self._processed and self._processed[0][0] < start:
            self._processed.popleft()
        for times in self._stages.values():
            while times and times[0][0] < start:
                times.popleft()

    def arrived(self, now):
        """One frame arrived at `now`."""
        self.received += 1
        self.last_arrival = now
        self._arrivals.append(now)
        self._trim(now)

    def done(self, now, latency, compute, stages=None):
        """One frame processed and published at `now`, latency (s) after its stamp, in compute (s);
        stages: {name: s} of the parts of that work (optional)."""
        self.processed += 1
        self._processed.append((now, float(latency), float(compute)))
        for name, seconds in (stages or {}).items():
            self._stages.setdefault(name, collections.deque()).append((now, float(seconds)))
        self._trim(now)

    def refused(self):
        """One frame dropped as unusable."""
        self.dropped += 1

    def summary(self, now):
        """A dict of the figures at `now`: input_rate, processed_rate (Hz, over the window),
        latency_p50/p90/p99 and compute_mean/compute_p90 (s, over the window; NaN for no frame),
        stages ({name: (p50 s, p90 s, frames)} over the window, in the order first seen),
        received, processed, dropped (counts since the start) and since_last_input (s, None
        before the first)."""
        self._trim(now)
        latency = percentiles(p[1] for p in self._processed)
        compute = [p[2] for p in self._processed]
        stages = {}
        for name, times in self._stages.items():
            if times:
                q = percentiles((t[1] for t in times), (50, 90))
                stages[name] = (q[50], q[90], len(times))
        return {"input_rate": len(self._arrivals) / self.window, "processed_rate": len(self._processed) / self.window,
                "latency_p50": latency[50], "latency_p90": latency[90], "latency_p99": latency[99],
                "compute_mean": float(np.mean(compute)) if compute else float("nan"),
                "compute_p90": percentiles(compute, (90,))[90], "stages": stages,
                "received": self.received, "processed": self.processed, "dropped": self.dropped,
                "since_last_input": None if self.last_arrival is None else now - self.last_arrival}

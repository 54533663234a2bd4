"""A live stream's plumbing, without ROS: the newest-frame slot and the stream's figures.

:class:`NewestFrame` hands a worker the newest item of a stream: a new item replaces one still
waiting (counted as skipped), so a slow worker always works on the latest frame and never on a
backlog. :class:`StreamStats` keeps a sliding window of arrivals and processed frames and gives
the rates, skipped frames, latency percentiles and compute per frame that can_tracker reports on
/diagnostics. Times in seconds.
"""
import collections
import threading

import numpy as np


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
    caller's clock, s): input and processed rates, latency (output time minus the input's stamp)
    and compute (s per processed frame); plus counts since the start. Not thread-safe: callers
    hold their lock."""

    def __init__(self, window=5.0):
        if not window > 0:
            raise ValueError(f"the window must be > 0 s, got {window}")
        self.window = float(window)
        self._arrivals = collections.deque()
        self._processed = collections.deque()  # (time, latency, compute)
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

    def arrived(self, now):
        """One frame arrived at `now`."""
        self.received += 1
        self.last_arrival = now
        self._arrivals.append(now)
        self._trim(now)

    def done(self, now, latency, compute):
        """One frame processed and published at `now`, latency (s) after its stamp, in compute (s)."""
        self.processed += 1
        self._processed.append((now, float(latency), float(compute)))
        self._trim(now)

    def refused(self):
        """One frame dropped as unusable."""
        self.dropped += 1

    def summary(self, now):
        """A dict of the figures at `now`: input_rate, processed_rate (Hz, over the window),
        latency_p50/p90/p99 and compute_mean/compute_p90 (s, over the window; NaN for no frame),
        received, processed, dropped (counts since the start) and since_last_input (s, None
        before the first)."""
        self._trim(now)
        latency = percentiles(p[1] for p in self._processed)
        compute = [p[2] for p in self._processed]
        return {"input_rate": len(self._arrivals) / self.window, "processed_rate": len(self._processed) / self.window,
                "latency_p50": latency[50], "latency_p90": latency[90], "latency_p99": latency[99],
                "compute_mean": float(np.mean(compute)) if compute else float("nan"),
                "compute_p90": percentiles(compute, (90,))[90],
                "received": self.received, "processed": self.processed, "dropped": self.dropped,
                "since_last_input": None if self.last_arrival is None else now - self.last_arrival}

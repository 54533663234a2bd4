"""A live stream's plumbing, without ROS: a bounded queue between the receiving thread and the
workers, and the count of frames lost on the way.

:class:`FrameQueue` never blocks the receiving thread: when full, the oldest frame is discarded.
:class:`DropCounter` counts the frames lost on the way (sequence gaps) and those discarded here.
"""
from __future__ import annotations

import collections
import threading
import time
from typing import Deque, Dict, Optional


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

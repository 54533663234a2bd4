"""pcd_save: snapshots of a live sensor_msgs/PointCloud2 stream written to PCD files.

``rosrun example_pcl pcd_save`` subscribes to ``kinect/depth/points`` (relative, so
/kinect/depth/points by default and remappable), writes the next cloud it receives to
``test_pcd.pcd`` in the current directory (ASCII), says where, and exits 0.

Private params (logged at start-up with the resolved topic):

- ``~file`` (str, default ``test_pcd.pcd``): the destination. With ``~count`` other than 1 the
  files are numbered: ``test_pcd_000000.pcd``, ``test_pcd_000001.pcd``, ...
- ``~format`` (ascii | binary | binary_compressed, default ascii).
- ``~count`` (int, default 1): 1 = one snapshot then exit, N = N snapshots then exit, 0 = until
  shutdown.
- ``~timeout`` (s, default 0 = wait forever): wall time allowed without a valid cloud, from
  start-up and then since the previous cloud; past it the node says so and exits 2.
- ``~queue_size`` (clouds, default 4): clouds buffered for the writers; when full the oldest is
  discarded and counted as dropped.
- ``~writers`` (default 2): writer threads (PCL's writer releases the GIL, so they run in parallel).
- ``~report_period`` (s, default 5): how often continuous mode logs its rate and drops.
- ``~max_points`` (default 5000000, 0 = no limit): larger clouds are dropped with a warning.

Every field of the message is kept (padding bytes are not fields and are left out), with the
organized width x height, is_dense and NaN points. PCD has no place for a frame id, so each PCD
file gets a sidecar ``<file>.json`` holding frame_id, stamp, seq, topic, publisher, the message's
layout and the wall time it was saved. Both files are written atomically (temporary name, fsync,
rename): a kill, a crash or a full disk never leaves a partial file under a final name.

Exit codes: 0 the requested snapshots were written (or, with ~count 0, shutdown was requested);
1 bad configuration or an unwritable destination (reported at start-up, before any cloud arrives);
2 timeout; 3 a write failed (disk full, directory removed); 130 interrupted before ~count snapshots.
"""
from __future__ import annotations

import collections
import ctypes
import dataclasses
import datetime
import json
import os
import re
import signal
import tempfile
import threading
import time
from typing import Callable, Deque, Dict, Optional, Tuple

import numpy as np
from numpy.lib import recfunctions

from example_pcl import conversions
from example_pcl.conversions import dtype_to_fields
from example_pcl.errors import PerceptionError, warning_kind
from example_pcl.pcd import FORMATS, atomic_path, write_pcd

TOPIC = "kinect/depth/points"

EXIT_OK = 0
EXIT_CONFIG = 1
EXIT_TIMEOUT = 2
EXIT_WRITE_FAILED = 3
EXIT_INTERRUPTED = 130


# ----------------------------------------------------------------------------------------------
# Configuration
# ----------------------------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class SaveConfig:
    """The effective configuration of pcd_save (see the module docstring for each field)."""

    file: str = "test_pcd.pcd"
    format: str = "ascii"
    count: int = 1
    timeout: float = 0.0
    queue_size: int = 4
    writers: int = 2
    report_period: float = 5.0
    max_points: int = 5_000_000

    @classmethod
    def from_params(cls, get_param: Callable[[str, object], object]) -> "SaveConfig":
        """Reads ``~name`` params through ``get_param(name, default)`` (e.g. rospy.get_param) and validates.

        ``file`` is made absolute against the current directory. Raises PerceptionError naming the
        offending param.
        """
        defaults = cls()
        raw = {f.name: get_param("~" + f.name, getattr(defaults, f.name)) for f in dataclasses.fields(cls)}
        try:
            config = cls(file=os.path.abspath(os.path.expanduser(str(raw["file"]))),
                         format=str(raw["format"]).strip().lower(),
                         count=int(raw["count"]), timeout=float(raw["timeout"]),
                         queue_size=int(raw["queue_size"]), writers=int(raw["writers"]),
                         report_period=float(raw["report_period"]), max_points=int(raw["max_points"]))
        except (TypeError, ValueError) as e:
            raise PerceptionError(f"bad parameter value: {e}") from None
        config.validate()
        return config

    def validate(self) -> None:
        """Raises PerceptionError for values the node cannot run with."""
        if self.format not in FORMATS:
            raise PerceptionError(f"~format must be one of {', '.join(FORMATS)}, got '{self.format}'")
        if self.count < 0:
            raise PerceptionError(f"~count must be >= 0 (0 = until shutdown), got {self.count}")
        if not self.timeout >= 0:
            raise PerceptionError(f"~timeout must be >= 0 s (0 = wait forever), got {self.timeout}")
        if self.queue_size < 1:
            raise PerceptionError(f"~queue_size must be >= 1, got {self.queue_size}")
        if self.writers < 1:
            raise PerceptionError(f"~writers must be >= 1, got {self.writers}")
        if self.max_points < 0:
            raise PerceptionError(f"~max_points must be >= 0 (0 = no limit), got {self.max_points}")
        if not self.report_period > 0:
            raise PerceptionError(f"~report_period must be > 0 s, got {self.report_period}")


# ----------------------------------------------------------------------------------------------
# Pure functions: names, destination check, validation, metadata, the write
# ----------------------------------------------------------------------------------------------

def snapshot_path(base: str, index: int, count: int) -> str:
    """The file for snapshot ``index`` (0-based) of ``count`` (0 = unbounded).

    ``count`` 1 writes ``base`` itself; otherwise ``stem_000042.ext`` beside it, six digits so the
    names sort in order for hours at 30 Hz.
    """
    if count == 1:
        return base
    stem, ext = os.path.splitext(base)
    return f"{stem}_{index:06d}{ext}"


def sidecar_path(path: str) -> str:
    """The metadata file written beside a PCD file: ``<file>.json``."""
    return path + ".json"


def check_destination(path: str) -> None:
    """Raises PerceptionError unless files can be created atomically at ``path``.

    Checks that the directory exists and is one, that ``path`` is not a directory, and creates and
    removes a temporary file there (the only check that also holds for root, read-only mounts and
    ACLs).
    """
    directory = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(directory):
        what = "is not a directory" if os.path.exists(directory) else "does not exist"
        raise PerceptionError(f"cannot save to '{path}': '{directory}' {what}")
    if os.path.isdir(path):
        raise PerceptionError(f"cannot save to '{path}': it is a directory (~file names a file)")
    try:
        fd, tmp = tempfile.mkstemp(prefix=".pcd_save_check.", dir=directory)
        os.close(fd)
        os.unlink(tmp)
    except OSError as e:
        raise PerceptionError(f"cannot save to '{path}': directory '{directory}' is not writable "
                              f"({e.strerror})") from None


def validate_cloud(msg, max_points: int = 0) -> np.ndarray:
    """The points of a PointCloud2 as a structured array view; PerceptionError if it cannot be saved.

    :func:`example_pcl.conversions.validate_cloud`'s checks: field layout, data length, no
    points, no x/y/z, more than ``max_points`` (0 = no limit), no finite point.
    """
    return conversions.validate_cloud(msg, max_points=max_points or None)


def packed_points(points: np.ndarray) -> np.ndarray:
    """The named fields of ``points`` with padding removed, C-contiguous (a copy only if needed).

    A Kinect driver's x y z _ rgb _ _ _ (32-byte points) becomes x y z rgb (16 bytes); PCL would
    otherwise write the padding as fields named ``_``.
    """
    names = list(points.dtype.names)
    packed = recfunctions.repack_fields(points[names]) if points.dtype.itemsize != sum(
        points.dtype.fields[n][0].itemsize for n in names) else points
    return np.ascontiguousarray(packed)


def cloud_metadata(msg, topic: str, path: str, fmt: str, publisher: str = "",
                   saved_at: Optional[float] = None) -> dict:
    """What the sidecar records about a saved cloud: frame, stamp, source and the message layout.

    ``saved_at``: wall time (s since the epoch), default now.
    """
    saved_at = time.time() if saved_at is None else saved_at
    return {
        "pcd_file": os.path.basename(path),
        "format": fmt,
        "topic": topic,
        "publisher": publisher,
        "frame_id": msg.header.frame_id,
        "stamp": {"secs": int(msg.header.stamp.secs), "nsecs": int(msg.header.stamp.nsecs)},
        "seq": int(msg.header.seq),
        "width": int(msg.width),
        "height": int(msg.height),
        "is_dense": bool(msg.is_dense),
        "point_step": int(msg.point_step),
        "row_step": int(msg.row_step),
        "fields": [{"name": f.name, "offset": int(f.offset), "datatype": int(f.datatype), "count": int(f.count)}
                   for f in msg.fields],
        "saved_wall_time": saved_at,
        "saved_wall_time_iso": datetime.datetime.fromtimestamp(saved_at, datetime.timezone.utc).isoformat(),
    }


def write_sidecar(path: str, metadata: dict) -> None:
    """Writes ``metadata`` as JSON to ``path``, atomically (temporary name, fsync, rename)."""
    with atomic_path(path) as tmp:
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump(metadata, f, indent=2, sort_keys=True)
            f.write("\n")


def save_cloud(path: str, msg, fmt: str, topic: str, publisher: str = "", max_points: int = 0,
               points: Optional[np.ndarray] = None) -> dict:
    """Writes a PointCloud2 to a PCD file and its ``<file>.json`` sidecar, both atomically.

    Every named field, the organized shape, is_dense and NaN points are kept; ascii uses 9
    significant digits so float32 values read back exactly. ``points``: the message's points as
    :func:`validate_cloud` already returned them (the node validates each cloud as it arrives);
    without it the message is validated here. Returns the sidecar's metadata.
    Raises PerceptionError for a cloud that cannot be saved, OSError when the disk or directory
    fails (nothing is then left under either final name).
    """
    points = packed_points(validate_cloud(msg, max_points) if points is None else points)
    write_pcd(path, points, fmt=fmt, is_dense=bool(msg.is_dense), precision=9)
    metadata = cloud_metadata(msg, topic, path, fmt, publisher)
    write_sidecar(sidecar_path(path), metadata)
    return metadata


# ----------------------------------------------------------------------------------------------
# Drop accounting and the bounded queue
# ----------------------------------------------------------------------------------------------

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


# ----------------------------------------------------------------------------------------------
# The writers: a pool of threads that takes clouds from the queue and saves them
# ----------------------------------------------------------------------------------------------

class SnapshotWriter:
    """Saves queued clouds with ``writers`` threads until ``count`` are written (0 = until closed).

    ROS-free: feed it with :meth:`submit` (cheap, never blocks), wait on :attr:`done`. File
    numbers follow the order clouds are taken from the queue. A cloud the writer rejects
    (PerceptionError) is reported through ``on_reject`` and does not count. A failed write
    (OSError: disk full, directory removed) stops a writer that must deliver ``count`` snapshots
    (``error`` holds it); in continuous mode (count 0) the error may be transient, so it is
    reported through ``on_write_error``, counted in ``failed`` and the writer carries on.
    """

    def __init__(self, config: SaveConfig, topic: str, save: Callable = save_cloud,
                 on_saved: Callable[[str, dict], None] = lambda path, meta: None,
                 on_reject: Callable[[Exception], None] = lambda error: None,
                 on_write_error: Callable[[Exception], None] = lambda error: None):
        self.config = config
        self.topic = topic
        self.drops = DropCounter()
        self.queue = FrameQueue(config.queue_size)
        self.done = threading.Event()
        self.error: Optional[BaseException] = None
        self.saved = 0
        self.failed = 0
        self.discarded_at_shutdown = 0
        self.first_saved_at: Optional[float] = None
        self.last_saved_at: Optional[float] = None
        self._save, self._on_saved, self._on_reject = save, on_saved, on_reject
        self._on_write_error = on_write_error
        self._lock = threading.Lock()
        self._assigned = 0
        self._rejected = 0
        self._stopping = threading.Event()
        self._threads = [threading.Thread(target=self._run, name=f"pcd_save_writer_{i}", daemon=True)
                         for i in range(config.writers)]

    def start(self) -> "SnapshotWriter":
        for thread in self._threads:
            thread.start()
        return self

    def submit(self, msg, publisher: str = "", points: Optional[np.ndarray] = None) -> None:
        """Queues a cloud (with its points when already validated, handed to ``save``); records
        sequence gaps and counts a discard if the queue was full."""
        with self._lock:
            self.drops.observe(msg.header.seq, publisher)
            if self.done.is_set():
                return
        discarded = self.queue.put((msg, publisher, points))
        if discarded:
            with self._lock:
                self.drops.discarded(discarded)

    def _take_index(self) -> Optional[int]:
        with self._lock:
            count = self.config.count
            if count and self._assigned - self._rejected >= count:
                return None
            index = self._assigned
            self._assigned += 1
            return index

    def _run(self) -> None:
        while not self._stopping.is_set():
            item = self.queue.get(timeout=0.2)
            if item is None:
                continue
            index = self._take_index()
            if index is None:
                continue  # enough snapshots are in flight or written; done will be set by them
            msg, publisher, points = item
            path = snapshot_path(self.config.file, index, self.config.count)
            try:
                metadata = self._save(path, msg, self.config.format, self.topic, publisher, points=points)
            except PerceptionError as e:
                with self._lock:
                    self._rejected += 1
                self._on_reject(e)
                continue
            except OSError as e:
                if self.config.count == 0:
                    with self._lock:
                        self.failed += 1
                    self._on_write_error(e)
                    continue
                with self._lock:
                    self.error = e
                self.done.set()
                return
            with self._lock:
                now = time.monotonic()
                self.saved += 1
                self.first_saved_at = self.first_saved_at or now
                self.last_saved_at = now
                finished = self.config.count and self.saved >= self.config.count
            self._on_saved(path, metadata)
            if finished:
                self.done.set()

    def stop(self, timeout: float = 30.0) -> None:
        """Discards queued clouds, lets in-flight writes finish (each is atomic) and joins the threads."""
        self._stopping.set()
        left = self.queue.close()
        with self._lock:
            self.discarded_at_shutdown += left
        for thread in self._threads:
            thread.join(timeout)

    def rate(self) -> float:
        """Saved clouds per second between the first and the last save (0 before two saves)."""
        with self._lock:
            if self.saved < 2:
                return 0.0
            return (self.saved - 1) / max(self.last_saved_at - self.first_saved_at, 1e-9)


# ----------------------------------------------------------------------------------------------
# The node
# ----------------------------------------------------------------------------------------------

def keep_freed_memory(keep_bytes: int = 256 << 20) -> bool:
    """Makes glibc's malloc reuse freed blocks of up to 32 MB instead of handing them back to the kernel.

    Every cloud passes through several fresh blocks of its size (rospy's read, the message's data,
    the writer's buffers). By default glibc unmaps or trims such blocks as soon as they are freed,
    and the next cloud faults them in again page by page: a bare rospy subscriber to the 30 Hz
    4.9 MB Kinect stream spent 12-14 ms of CPU per message, 5 ms with freed memory kept. Blocks
    up to 32 MB (glibc's most) then come from the heap, and up to ``keep_bytes`` of it stay
    mapped when free. Process-wide, so only for a node's own process. Returns False, changing
    nothing, where the C library has no mallopt (not glibc).
    """
    try:
        mallopt = ctypes.CDLL("libc.so.6").mallopt
    except (OSError, AttributeError):
        return False
    m_trim_threshold, m_mmap_threshold = -1, -3  # glibc's malloc.h
    # Both: fixing either one turns off glibc's adaptive thresholds, and a fixed trim threshold
    # alone leaves every block above 128 KB to mmap (worse than the default).
    return bool(mallopt(m_mmap_threshold, 32 << 20)) and bool(mallopt(m_trim_threshold, keep_bytes))


class PcdSaveNode:
    """Subscribes to a PointCloud2 topic and saves clouds with a :class:`SnapshotWriter`.

    The subscriber callback only validates the message (a view, no copy) and queues it; writer
    threads do the work, so the receive thread is never blocked by a write.
    """

    def __init__(self, config: SaveConfig):
        import rospy
        from sensor_msgs.msg import PointCloud2

        self._rospy = rospy
        self.config = config
        self.topic = rospy.resolve_name(TOPIC)
        self.stop_requested = threading.Event()
        self.last_cloud_at = time.monotonic()
        self.malformed = 0
        self._warned_kinds = set()
        self.writer = SnapshotWriter(config, self.topic, on_saved=self._on_saved, on_reject=self._on_malformed,
                                     on_write_error=self._on_write_error)
        self.writer.start()
        # rospy allocates buff_size bytes for every recv(): at 64 MB each one mapped and faulted in
        # fresh memory (15 ms of CPU per 4.9 MB Kinect cloud against 9-10 ms at 1 MB). Nothing
        # is lost by reading less at a time: every cloud is still delivered, and when the node
        # falls behind the publisher's queue drops frames, which the sequence gaps count.
        self.subscriber = rospy.Subscriber(TOPIC, PointCloud2, self._on_cloud, queue_size=2, buff_size=1 << 20)

    def _on_cloud(self, msg) -> None:
        try:
            points = validate_cloud(msg, self.config.max_points)
        except PerceptionError as e:
            self._on_malformed(e)
            return
        self.last_cloud_at = time.monotonic()
        publisher = (getattr(msg, "_connection_header", None) or {}).get("callerid", "")
        self.writer.submit(msg, publisher, points)

    def _on_malformed(self, error: Exception) -> None:
        self.malformed += 1
        kind = warning_kind(error)
        if kind not in self._warned_kinds:
            self._warned_kinds.add(kind)
            self._rospy.logwarn("dropping a malformed cloud on %s: %s (further clouds of this kind are dropped "
                                "silently and counted)", self.topic, error)

    def _on_write_error(self, error: Exception) -> None:
        self._rospy.logerr_throttle(5.0, f"writing a snapshot failed ({self.writer.failed} so far), carrying on: "
                                         f"{error}")

    def _on_saved(self, path: str, metadata: dict) -> None:
        if self.config.count == 1:
            self._rospy.loginfo("saved the cloud from %s (frame '%s', stamp %d.%09d, %dx%d) to %s",
                                self.topic, metadata["frame_id"], metadata["stamp"]["secs"],
                                metadata["stamp"]["nsecs"], metadata["width"], metadata["height"], path)
        else:
            self._rospy.logdebug("saved %s", path)

    def _progress(self) -> str:
        return (f"saved {self.writer.saved} of {self.writer.drops.received} clouds received on {self.topic} "
                f"({self.writer.rate():.1f} Hz), {self.writer.drops.summary()}, {self.malformed} malformed, "
                f"{self.writer.failed} failed writes")

    def request_stop(self) -> None:
        """Asks :meth:`spin` to finish: in-flight writes complete, queued clouds are discarded."""
        self.stop_requested.set()

    def spin(self) -> int:
        """Waits for the snapshots, a timeout or a stop request; returns the exit code."""
        rospy, config = self._rospy, self.config
        code = EXIT_OK
        next_report = time.monotonic() + config.report_period
        while True:
            if self.writer.done.wait(0.1):
                break
            if config.count != 1 and time.monotonic() >= next_report:
                next_report += config.report_period
                rospy.loginfo(self._progress())
            if self.stop_requested.is_set() or rospy.is_shutdown():
                code = EXIT_OK if config.count == 0 else EXIT_INTERRUPTED
                break
            silent = time.monotonic() - self.last_cloud_at
            if config.timeout and silent > config.timeout:
                publishers = self.subscriber.get_num_connections()
                rospy.logerr("no %scloud on %s within %.1f s (~timeout); %d publisher(s) connected%s",
                             "valid " if self.malformed else "", self.topic, config.timeout, publishers,
                             f", {self.malformed} malformed cloud(s) dropped" if self.malformed else
                             "" if publishers else f": is a publisher running? (rostopic info {self.topic})")
                code = EXIT_TIMEOUT
                break
        self.subscriber.unregister()
        self.writer.stop()
        if self.writer.error is not None:
            rospy.logerr("writing a snapshot failed, stopping: %s", self.writer.error)
            code = EXIT_WRITE_FAILED
        elif code == EXIT_INTERRUPTED and self.writer.saved >= max(config.count, 1):
            code = EXIT_OK
        if config.count != 1 or code != EXIT_OK:
            rospy.loginfo("pcd_save done: %s%s", self._progress(),
                          f", {self.writer.discarded_at_shutdown} queued cloud(s) discarded at shutdown"
                          if self.writer.discarded_at_shutdown else "")
        return code


def main(argv=None) -> int:
    """Entry point of ``rosrun example_pcl pcd_save``; returns the exit code."""
    import sys

    import rospy

    keep_freed_memory()
    rospy.init_node("pcd_save", argv=sys.argv if argv is None else argv, disable_signals=True)
    try:
        config = SaveConfig.from_params(rospy.get_param)
        check_destination(snapshot_path(config.file, 0, config.count))
    except PerceptionError as e:
        rospy.logfatal("pcd_save: %s", e)
        rospy.signal_shutdown("bad configuration")
        return EXIT_CONFIG
    node = PcdSaveNode(config)
    what = {1: "the next cloud"}.get(config.count, f"{config.count} clouds" if config.count else
                                     "every cloud until shutdown")
    rospy.loginfo("pcd_save: writing %s from %s to %s (format %s, count %d, timeout %s, queue %d, writers %d)",
                  what, node.topic, snapshot_path(config.file, 0, config.count) if config.count == 1 else
                  snapshot_path(config.file, 0, config.count).replace("000000", "NNNNNN"),
                  config.format, config.count, f"{config.timeout:g} s" if config.timeout else "none",
                  config.queue_size, config.writers)

    def on_signal(signum, frame):
        node.request_stop()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    code = node.spin()
    rospy.signal_shutdown("pcd_save finished")
    return code

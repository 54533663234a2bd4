"""Snapshots of a PointCloud2 stream as PCD files, each with a JSON sidecar; ROS-free.

:func:`save_cloud` writes one message: every named field (padding left out), the organized
width x height, is_dense and NaN points, to a PCD file, and what PCD has no place for (frame id,
stamp, seq, topic, publisher, the message's layout, the wall time) to ``<file>.json``. Both are
written atomically (temporary name, fsync, rename): a kill, a crash or a full disk never leaves a
partial file under a final name. :class:`SnapshotWriter` saves a stream of them with a pool of
threads fed through a :class:`~example_pcl.frame_stream.FrameQueue`, numbering the files
(:func:`snapshot_path`). :class:`SaveConfig` is pcd_save's configuration (its ``~params``).
"""
from __future__ import annotations

import dataclasses
import datetime
import json
import os
import tempfile
import threading
import time
from typing import Callable, Optional

import numpy as np
from numpy.lib import recfunctions

from example_pcl import conversions
from example_pcl.errors import PerceptionError
from example_pcl.frame_stream import DropCounter, FrameQueue
from example_pcl.pcd import FORMATS, atomic_path, write_pcd


@dataclasses.dataclass(frozen=True)
class SaveConfig:
    """The effective configuration of pcd_save: its ``~params``, each described in
    :mod:`example_pcl.pcd_save_node`'s docstring (file, format, count, queue_size and writers are
    the writer's; timeout, report_period and max_points the node's)."""

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


# --- files: names, destination check, validation, metadata, the write ----------------------------

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


# --- the writers: a pool of threads that takes clouds from the queue and saves them ---------------

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

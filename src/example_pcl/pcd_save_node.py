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

Every field, the organized shape, is_dense and NaN points are kept; each PCD file gets a sidecar
``<file>.json`` with the frame id, stamp and source PCD cannot hold; both are written atomically
(see :mod:`example_pcl.snapshot`, which does the writing; this module is the node).

Exit codes: 0 the requested snapshots were written (or, with ~count 0, shutdown was requested);
1 bad configuration or an unwritable destination (reported at start-up, before any cloud arrives);
2 timeout; 3 a write failed (disk full, directory removed); 130 interrupted before ~count snapshots.
"""
from __future__ import annotations

import signal
import threading
import time

from example_pcl.errors import OncePerKind, PerceptionError
from example_pcl.memory import keep_freed_memory
from example_pcl.snapshot import SaveConfig, SnapshotWriter, check_destination, snapshot_path, validate_cloud

TOPIC = "kinect/depth/points"

EXIT_OK = 0
EXIT_CONFIG = 1
EXIT_TIMEOUT = 2
EXIT_WRITE_FAILED = 3
EXIT_INTERRUPTED = 130


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
        self._malformed_kinds = OncePerKind(rospy.logwarn)  # the rest dropped silently, counted
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
        self._malformed_kinds(f"dropping a malformed cloud on {self.topic}", error)

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

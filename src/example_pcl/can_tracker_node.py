"""can_tracker: every can on the table of a live point cloud stream, tracked with stable ids.

``rosrun example_pcl can_tracker`` (or ``roslaunch example_pcl can_tracker.launch cloud:=...``)
subscribes ``kinect/depth/points`` and, on the newest cloud each time, refits the known table and
cans (example_pcl.local_fit.BackgroundSearchFinder: the full search of mode 4 when needed, in a
worker thread of its own once a table is known), tracks the cans (example_pcl.tracking.CanTracker)
and publishes, stamped with the cloud's stamp, ``cans``, ``can_poses``, ``can_markers`` and
``table_marker``. Topics, params and set-up: docs/can_tracker.md.
"""
import concurrent.futures
import dataclasses
import sys
import threading
import time
import traceback
import types

import numpy as np
import rospy

from example_pcl import auto_finder as af
from example_pcl import geometry as g
from example_pcl import messages
from example_pcl.conversions import cloud_from_bytes, frozen_data, validate_cloud, xyz_view
from example_pcl.errors import OncePerKind, PerceptionError
from example_pcl.frame_stream import NewestFrame, StreamStats
from example_pcl.local_fit import BackgroundSearchFinder, LocalFitConfig
from example_pcl.reconfigure import tracker_from_values, tracker_param_names
from example_pcl.tracking import CanTracker, TrackerConfig

CLOUD_TOPIC = "kinect/depth/points"
CANS_TOPIC = "cans"
POSES_TOPIC = "can_poses"
MARKERS_TOPIC = "can_markers"
TABLE_TOPIC = "table_marker"
OUTPUT_TOPICS = (CANS_TOPIC, POSES_TOPIC, MARKERS_TOPIC, TABLE_TOPIC)
TF_ERROR_PERIOD = 5.0  # s between two logged errors about a missing transform
BUFF_SIZE = 1 << 26  # bytes: rospy's receive buffer, several 640x480 XYZRGB clouds
CLOUD_TYPE = "sensor_msgs/PointCloud2"


@dataclasses.dataclass(frozen=True)
class CanTrackerConfig:
    """The effective configuration of can_tracker. target_frame: outputs in this frame through
    tf2 at each cloud's stamp ("" = the cloud's frame); tf_timeout (s): how long to wait for that
    transform; lazy: work only while someone subscribes to an output; max_points: a bigger
    cloud is refused; stats_window (s): of the diagnostics' rates and percentiles; local,
    tracker: the LocalFitConfig (its .auto the full search's AutoConfig) and TrackerConfig."""

    target_frame: str = ""
    tf_timeout: float = 0.1
    lazy: bool = True
    max_points: int = 5_000_000
    stats_window: float = 5.0
    local: LocalFitConfig = LocalFitConfig()
    tracker: TrackerConfig = TrackerConfig()

    @classmethod
    def from_params(cls, get_param):
        """Reads the private params through ``get_param(name, default)`` (the finder's and the
        tracker's under their cfg/CanTracker.cfg names); raises PerceptionError for a value that
        cannot work."""
        try:
            names = tracker_param_names(LocalFitConfig(), TrackerConfig())
            values = {name: get_param("~" + name, None) for name in names}
            local, tracker, _ = tracker_from_values(LocalFitConfig(), TrackerConfig(),
                                                    {k: v for k, v in values.items() if v is not None})
            config = cls(target_frame=str(get_param("~target_frame", "") or "").strip().lstrip("/"),
                         tf_timeout=float(get_param("~tf_timeout", cls.tf_timeout)),
                         lazy=bool(get_param("~lazy", cls.lazy)),
                         max_points=int(get_param("~max_points", cls.max_points)),
                         stats_window=float(get_param("~stats_window", cls.stats_window)),
                         local=local, tracker=tracker)
        except (TypeError, ValueError) as e:
            raise PerceptionError(f"bad parameter value: {e}") from None
        if not config.tf_timeout >= 0:
            raise PerceptionError(f"~tf_timeout must be >= 0 s, got {config.tf_timeout}")
        if not config.max_points > 0:
            raise PerceptionError(f"~max_points must be > 0, got {config.max_points}")
        if not config.stats_window > 0:
            raise PerceptionError(f"~stats_window must be > 0 s, got {config.stats_window}")
        return config

    def describe(self):
        """One line: the values a user sets most, for the start-up log."""
        return (f"target_frame={self.target_frame or '(the cloud frame)'} tf_timeout={self.tf_timeout} s "
                f"lazy={self.lazy} max_points={self.max_points} search_period={self.local.search_period} frames "
                f"max_missed={self.tracker.max_missed} frames gate_distance={self.tracker.gate_distance} m")


class CanTrackerNode:
    """Wires a cloud stream to BackgroundSearchFinder + CanTracker and the results to publishers.

    publishers: {topic: object with publish(msg) and get_num_connections()} for OUTPUT_TOPICS;
    lookup(target, source, stamp, timeout) -> 4x4 T_target_from_source or PerceptionError (tf2
    in the node); log: an object with error, warn, info, debug (rospy's by default); now(): the
    time in seconds (ROS time in the node); search_executor: where the full search runs once a
    table is known (local_fit.BackgroundSearchFinder; None: on the frame that asks for it, then
    adopted by the next, deterministic for tests; the node passes a one-thread pool).
    process(msg) does one cloud's work (a PointCloud2, or the rospy.AnyMsg the subscriber gets)
    under the lock; start_ros() adds the subscriber (lazy), the worker thread, diagnostics and
    reconfigure.
    """

    def __init__(self, config, publishers, lookup=None, log=None, now=None, search_executor=None):
        self.config = config
        self.publishers = publishers
        self.lookup = lookup
        self.log = log or _rospy_log()
        self.now = now or time.time
        self.search_executor = search_executor
        self.lock = threading.Lock()  # one frame at a time, and reconfigure between frames
        self._stats_lock = threading.Lock()  # the callback's counters: it never waits for a frame
        self.stats = StreamStats(config.stats_window)
        self.slot = NewestFrame()
        self.tracker = CanTracker(config.tracker)
        self._finders = {}  # BackgroundSearchFinder per cloud frame_id: a second camera keeps its own table
        self._frame = None  # the frame the tracks are in without ~target_frame
        self._last_stamp = None
        self._table_shown = False
        self._once = OncePerKind(self.log.error, self.log.debug)
        self._notes = OncePerKind(self.log.warn, self.log.debug)
        self._last_tf_error = None
        self.last_update = None  # the last TrackerUpdate, for tests and diagnostics
        self.last_reason = ""  # why the last frame ran the full search ("" when it did not)
        self._subscriber = None
        self._ros = None

    # --- one frame ---

    def on_cloud(self, msg):
        """The subscriber's callback: counts the cloud and hands it to the worker (newest wins)."""
        now = self.now()
        with self._stats_lock:
            self.stats.arrived(now)
        self.slot.put((msg, now))

    def process(self, msg, received=None):
        """One cloud: validated, refitted, tracked, published. Bad input is logged (once per kind)
        and dropped; returns the TrackerUpdate, or None when the frame was dropped. The seconds
        of each stage go to the diagnostics (deserialise, convert, the fit's stages, tracker,
        messages; with received, the time (now()) the callback got it: delivery, from the
        cloud's stamp, and queue, until this work began)."""
        start = self.now()
        t0 = time.perf_counter()
        stages = {}
        with self.lock:
            update, stamp = self._process(msg, stages)
        with self._stats_lock:
            if update is None:
                self.stats.refused()
            else:
                now = self.now()
                if received is not None:
                    stages["delivery"], stages["queue"] = received - stamp, start - received
                self.stats.done(now, now - stamp, time.perf_counter() - t0, stages)
        return update

    def _process(self, msg, stages):
        c = self.config
        t = time.perf_counter()
        try:
            if hasattr(msg, "_buff"):  # rospy.AnyMsg: read here, the points viewed in its buffer
                kind = getattr(msg, "_connection_header", {}).get("type", CLOUD_TYPE)
                if kind != CLOUD_TYPE:
                    raise PerceptionError(f"a {kind} message on the cloud topic, not a {CLOUD_TYPE}")
                msg = cloud_from_bytes(msg._buff)
            t1 = time.perf_counter()
            xyz = xyz_view(validate_cloud(msg, c.max_points))
            frame = msg.header.frame_id.strip().lstrip("/")
            if not frame:
                raise PerceptionError("the cloud has no header.frame_id")
        except PerceptionError as e:
            self._once("can_tracker: cloud dropped", e)
            return None, None
        stages["deserialise"], stages["convert"] = t1 - t, time.perf_counter() - t1
        stamp = msg.header.stamp.to_sec()
        if not c.target_frame and self._frame not in (None, frame):
            if self._last_stamp is not None and 0 <= stamp - self._last_stamp <= c.tracker.max_gap:
                self._once("can_tracker: cloud dropped", PerceptionError(
                    f"cloud in frame '{frame}' while the cans are tracked in '{self._frame}'; set ~target_frame "
                    "to track the clouds of several frames in one"))
                return None, None
            switched = self.tracker.reset()
            self._notes("can_tracker", f"the clouds are now in frame '{frame}', no longer in '{self._frame}': "
                        f"tracks {switched} ended")
        else:
            switched = []
        out_frame = c.target_frame or frame
        T_out_from_sensor = np.eye(4)
        if c.target_frame and c.target_frame != frame:
            try:
                T_out_from_sensor = self.lookup(c.target_frame, frame, msg.header.stamp, c.tf_timeout)
            except PerceptionError as e:
                self._tf_error(e)
                return None, None
        finder = self._finders.get(frame)
        if finder is None:
            finder = self._finders[frame] = BackgroundSearchFinder(c.local, executor=self.search_executor)
        cans, T_sensor_from_plane, self.last_reason = [], None, ""
        t = time.perf_counter()
        try:
            if xyz.ndim == 3:  # the view of the message's points: the refit reads it in place
                fit = finder.process(xyz, frozen=frozen_data(msg))
                self.last_reason = fit.reason
                stages.update(fit.timings)
            else:  # an unorganized cloud has no pixel neighbourhoods to refit in: the full search each time
                fit = af.find_cans(xyz, (0.0, 0.0, 0.0), c.local.auto)
                self.last_reason = "unorganized cloud"
                stages["search"] = time.perf_counter() - t
            cans, T_sensor_from_plane = list(fit.cans), fit.T_sensor_from_plane
        except PerceptionError as e:
            self._once("can_tracker: no table in this frame", e)
        stages["fit"] = stages.pop("total", time.perf_counter() - t)
        t = time.perf_counter()
        moved = [dataclasses.replace(can, T_sensor_from_can=T_out_from_sensor @ can.T_sensor_from_can) for can in cans]
        update = self.tracker.update(moved, stamp)
        if switched:
            update = dataclasses.replace(update, ended=switched + update.ended)
        if update.reset:
            self._notes("can_tracker", update.reset)
            self._finders = {frame: finder}  # the other cameras' tables are from before the jump too
        for event in update.events:
            if event != update.reset:
                self._notes("can_tracker", event)
        self._frame, self._last_stamp, self.last_update = frame, stamp, update
        stages["tracker"] = time.perf_counter() - t
        t = time.perf_counter()
        self._publish(update, out_frame, msg.header.stamp, xyz, T_sensor_from_plane, T_out_from_sensor)
        stages["messages"] = time.perf_counter() - t
        return update, stamp

    def _tf_error(self, error):
        """A missing transform: an error at most every TF_ERROR_PERIOD seconds, else debug."""
        now = time.monotonic()
        if self._last_tf_error is None or now - self._last_tf_error >= TF_ERROR_PERIOD:
            self._last_tf_error = now
            self.log.error("can_tracker: frame skipped: %s (logged at most every %.0f s)", error, TF_ERROR_PERIOD)
        else:
            self.log.debug("can_tracker: frame skipped: %s", error)

    # --- outputs ---

    def _publish(self, update, frame, stamp, xyz, T_sensor_from_plane, T_out_from_sensor):
        """Each output that someone subscribes to (none is latched: a message nobody gets is not built)."""
        p = self.publishers
        if p[CANS_TOPIC].get_num_connections() > 0:
            p[CANS_TOPIC].publish(messages.track_array(update.tracks, frame, stamp))
        if p[POSES_TOPIC].get_num_connections() > 0:
            p[POSES_TOPIC].publish(messages.track_poses(update.tracks, frame, stamp))
        if p[MARKERS_TOPIC].get_num_connections() > 0:
            p[MARKERS_TOPIC].publish(messages.track_markers(update.tracks, update.ended, frame, stamp))
        table = p[TABLE_TOPIC]
        extent = None
        if T_sensor_from_plane is not None and table.get_num_connections() > 0:
            extent = g.plane_extent(xyz, T_sensor_from_plane, self.config.local.table_band)
        if extent is not None:
            table.publish(messages.table_marker(T_out_from_sensor @ T_sensor_from_plane, extent, frame, stamp))
            self._table_shown = True
        elif self._table_shown:
            table.publish(messages.delete_marker(frame, ns=messages.TABLE_NS))
            self._table_shown = False

    # --- reconfigure ---

    def reconfigure(self, values):
        """New tolerances from the next frame: a changed search or refit starts the finders afresh
        (the next frame runs the full search); the tracks are kept. Returns the log lines; raises
        PerceptionError (nothing changed) for values that cannot work."""
        with self.lock:
            local, tracker, changes = tracker_from_values(self.config.local, self.config.tracker, values)
            if local != self.config.local:
                self._finders = {}
            self.tracker.config = tracker
            self.config = dataclasses.replace(self.config, local=local, tracker=tracker)
            return changes

    # --- diagnostics ---

    def diagnose(self):
        """(level: 0 OK, 1 WARN, message, [(key, value)]) of the stream for /diagnostics."""
        with self._stats_lock:
            s = self.stats.summary(self.now())
        skipped = self.slot.skipped
        ms = lambda v: "n/a" if not np.isfinite(v) else f"{1e3 * v:.1f}"  # noqa: E731
        tracks = len(self.last_update.tracks) if self.last_update else 0
        values = [("input rate (Hz)", f"{s['input_rate']:.1f}"), ("processed rate (Hz)", f"{s['processed_rate']:.1f}"),
                  ("received", str(s["received"])), ("processed", str(s["processed"])), ("skipped", str(skipped)),
                  ("dropped (bad input, no transform)", str(s["dropped"])),
                  ("latency p50 (ms)", ms(s["latency_p50"])), ("latency p90 (ms)", ms(s["latency_p90"])),
                  ("latency p99 (ms)", ms(s["latency_p99"])), ("compute mean (ms/frame)", ms(s["compute_mean"])),
                  ("compute p90 (ms/frame)", ms(s["compute_p90"])),
                  ("tracks", str(tracks)),
                  ("subscribed to the input", str(self._subscriber is not None or self._ros is None))]
        stages = [(f"stage {name} p50 / p90 (ms, frames)", f"{ms(p50)} / {ms(p90)} ({n})")
                  for name, (p50, p90, n) in s["stages"].items()]
        values += stages
        if self._ros is not None and self._subscriber is None:
            return 0, "idle: nobody subscribes to the outputs (~lazy)", values
        if s["since_last_input"] is None:
            return 1, "no cloud received yet", values
        if s["since_last_input"] > 2.0:
            return 1, f"no cloud for {s['since_last_input']:.1f} s", values
        if s["processed_rate"] < 0.9 * s["input_rate"]:
            return 1, f"processing {s['processed_rate']:.1f} of {s['input_rate']:.1f} clouds/s", values
        return 0, f"tracking {tracks} can(s) at {s['processed_rate']:.1f} Hz", values

    # --- ROS wiring ---

    def start_ros(self):
        """The subscriber (now, or while someone listens with ~lazy), the worker, diagnostics,
        reconfigure and clean shutdown. Needs rospy.init_node."""
        import diagnostic_updater
        from dynamic_reconfigure.server import Server

        from example_pcl.cfg import CanTrackerConfig as CanTrackerReconfigure

        self._ros = rospy
        self._worker = threading.Thread(target=self._work, name="can_tracker_worker", daemon=True)
        self._worker.start()
        rospy.on_shutdown(self.slot.close)
        if self.search_executor is not None:
            rospy.on_shutdown(lambda: self.search_executor.shutdown(wait=False, cancel_futures=True))
        self._updater = diagnostic_updater.Updater()
        self._updater.setHardwareID("none")
        self._updater.add("stream", self._diagnostic_task)
        self._diagnostic_timer = rospy.Timer(rospy.Duration(1.0), lambda _: self._updater.update())
        self._reconfigure_values = None
        self._reconfigure_server = Server(CanTrackerReconfigure, self._on_reconfigure)
        self.connections_changed()

    def connections_changed(self, *_):
        """Subscribes to the input while someone subscribes to an output (or always without ~lazy)."""
        if self._ros is None:
            return
        wanted = not self.config.lazy or any(p.get_num_connections() > 0 for p in self.publishers.values())
        with self._stats_lock:
            if wanted and self._subscriber is None:
                # AnyMsg: rospy's receiving thread leaves the bytes as they came; the worker reads the
                # header and views the points in place (conversions.cloud_from_bytes), where genpy would
                # copy them. tcp_nodelay: the sender's small writes are not held back (Nagle).
                self._subscriber = self._ros.Subscriber(CLOUD_TOPIC, self._ros.AnyMsg, self.on_cloud, queue_size=1,
                                                        buff_size=BUFF_SIZE, tcp_nodelay=True)
                self.log.info("can_tracker: subscribed to %s", self._ros.resolve_name(CLOUD_TOPIC))
            elif not wanted and self._subscriber is not None:
                self._subscriber.unregister()
                self._subscriber = None
                self.log.info("can_tracker: nobody subscribes to the outputs: unsubscribed from %s (~lazy)",
                              self._ros.resolve_name(CLOUD_TOPIC))

    def _work(self):
        while True:
            item = self.slot.take()
            if item is None:
                return
            try:
                self.process(*item)
            except Exception:  # noqa: BLE001 - a bug on one frame must not stop the tracker
                self.log.error("can_tracker: internal error, frame dropped:\n%s", traceback.format_exc())

    def _diagnostic_task(self, stat):
        level, message, values = self.diagnose()
        stat.summary(level, message)
        for key, value in values:
            stat.add(key, value)
        return stat

    def _on_reconfigure(self, values, level):
        try:
            changes = self.reconfigure(values)
        except PerceptionError as e:
            self.log.error("can_tracker: reconfigure refused, previous values kept: %s", e)
            return self._reconfigure_values or values
        if changes and self._reconfigure_values is not None:
            self.log.info("can_tracker: reconfigured (from the next frame): %s", ", ".join(changes))
        self._reconfigure_values = dict(values)
        return values


def _rospy_log():
    return types.SimpleNamespace(error=rospy.logerr, warn=rospy.logwarn, info=rospy.loginfo, debug=rospy.logdebug)


def tf2_lookup(buffer):
    """lookup(target, source, stamp, timeout) over a tf2_ros.Buffer: the 4x4 T_target_from_source
    at stamp (rospy.Time), waiting up to timeout (s); PerceptionError when tf2 has none."""
    import tf2_ros

    def lookup(target, source, stamp, timeout):
        try:
            tf = buffer.lookup_transform(target, source, stamp, rospy.Duration(timeout))
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException) as e:
            raise PerceptionError(f"no transform from '{source}' to ~target_frame '{target}' at the cloud's stamp "
                                  f"{stamp.to_sec():.3f}: {e}") from None
        return messages.matrix_from_transform(tf.transform)

    return lookup


def main(argv=None):
    """Entry point of ``rosrun example_pcl can_tracker``; returns the exit code."""
    import tf2_ros
    from geometry_msgs.msg import PoseArray
    from visualization_msgs.msg import Marker, MarkerArray

    from example_pcl.msg import CanArray

    rospy.init_node("can_tracker", argv=sys.argv if argv is None else argv)
    try:
        config = CanTrackerConfig.from_params(rospy.get_param)
    except PerceptionError as e:
        rospy.logfatal("can_tracker: %s", e)
        return 1
    buffer = tf2_ros.Buffer()
    listener = tf2_ros.TransformListener(buffer)  # noqa: F841 - fills the buffer while it lives
    connections = _ConnectionListener()
    kinds = {CANS_TOPIC: CanArray, POSES_TOPIC: PoseArray, MARKERS_TOPIC: MarkerArray, TABLE_TOPIC: Marker}
    publishers = {topic: rospy.Publisher(topic, kind, queue_size=2, subscriber_listener=connections)
                  for topic, kind in kinds.items()}
    # One worker for the full search: it runs beside the frames, never two at once.
    search = concurrent.futures.ThreadPoolExecutor(max_workers=1, thread_name_prefix="can_tracker_search")
    node = CanTrackerNode(config, publishers, lookup=tf2_lookup(buffer), now=rospy.get_time, search_executor=search)
    connections.changed = node.connections_changed
    node.start_ros()
    rospy.loginfo("can_tracker: %s", config.describe())
    rospy.loginfo("can_tracker: input %s, outputs %s", rospy.resolve_name(CLOUD_TOPIC),
                  " ".join(rospy.resolve_name(t) for t in OUTPUT_TOPICS))
    rospy.spin()
    return 0


class _ConnectionListener(rospy.SubscribeListener):
    """Calls `changed` (set once the node exists) when an output gains or loses a subscriber."""

    changed = None

    def peer_subscribe(self, topic_name, topic_publish, peer_publish):
        if self.changed is not None:
            self.changed()

    def peer_unsubscribe(self, topic_name, num_peers):
        if self.changed is not None:
            self.changed()

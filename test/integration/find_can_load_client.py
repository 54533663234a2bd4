#!/usr/bin/python3
"""The ROS side of test_find_can_load.py: loads a running find_can and records every answer.

    find_can_load_client.py sequential CALLS OUT.json
    find_can_load_client.py concurrent CLIENTS CALLS_PER_CLIENT OUT.json

``sequential``: the operator's walkthrough and its out-of-order calls (SEQUENTIAL_CYCLE) again and
again until CALLS process_mode calls are made, one at a time, each selection acknowledged before
the next call, alternating between pixel-rectangle selections and clicks; the can pose published
after each successful mode 2, 3 or 4 is recorded with its answer.

``concurrent``: CLIENTS threads, each with its own ServiceProxy (every other one persistent), make
CALLS_PER_CLIENT calls each of modes drawn from STORM_MODES (seeded), while another thread keeps
publishing selections alternating between the table and the can patch on selected_points and
clicked_point (STORM_SELECTIONS); then one last selection on each topic is acknowledged and the
walkthrough (example_pcl.find_can_client.walkthrough, the demo's) runs once more, clean.

Every call is watched: one unanswered after CALL_TIMEOUT s ends the run (exit status 3) with the
record written. The record (JSON) is checked by test_find_can_load.py, which replays it on
example_pcl.can_finder.CanFinder. The patches are defined here for both sides (selection_points).
"""
import json
import os
import random
import sys
import threading
import time

import numpy as np

from example_pcl.find_can_client import CAN_RECT, TABLE_RECT

CALL_TIMEOUT = 30.0  # s: liveness only (a call takes milliseconds); longer means the node hangs
# Pixels (v, u) of the bundled scene a click selects around: the table left of and below the can,
# and the middle of the can's side facing the sensor.
TABLE_PIXEL = (390, 110)
CAN_PIXEL = (227, 319)
# name -> (topic, what): a pixel rectangle sent as points, a click at a pixel's point, or the
# points a click at that pixel selects sent as points (so the table and can patches are the same
# points whichever topic brings them).
SELECTIONS = {
    "table_rect": ("selected_points", TABLE_RECT), "can_rect": ("selected_points", CAN_RECT),
    "table_click": ("clicked_point", TABLE_PIXEL), "can_click": ("clicked_point", CAN_PIXEL),
    "table_near": ("selected_points", TABLE_PIXEL), "can_near": ("selected_points", CAN_PIXEL),
}
# One cycle of the sequential run: "table"/"can" select a patch, numbers are process_mode calls:
# out of order (2 before the plane, 3 before mode 1, 2 before a can patch, 3 before mode 2), the
# walkthrough, mode 3 again, mode 4, modes 1 and 3 after mode 4, and an unknown mode.
SEQUENTIAL_CYCLE = ("table", 2, 0, 3, 1, 2, 3, "can", 2, 3, 3, 4, 1, 3, 5)
STORM_MODES = (0, 1, 1, 2, 2, 3, 3, 4, 5)  # what the concurrent clients call, uniformly drawn
STORM_SELECTIONS = ("table_near", "can_click", "table_click", "can_near")  # sent in turn, 50 per second
STORM_SEED = 6


def selection_points(name, xyz, finder):
    """The points find_can stores for the named selection (float32 (K, 3), sensor frame) and the
    clicked point (float64 (3,)) or None; finder: a CanFinder on xyz (for points_near)."""
    from example_pcl.find_can_node import FindCanConfig
    from example_pcl.select_patch import select_points

    topic, what = SELECTIONS[name]
    if name.endswith("_rect"):
        return select_points(xyz, rect=what), None
    point = xyz[what].astype(float)
    return finder.points_near(point, FindCanConfig.patch_radius), point


class Recorder:
    """Calls process_mode and records each answer; a watchdog thread ends the run when a call stays
    unanswered for CALL_TIMEOUT s."""

    def __init__(self, out_path):
        self.out_path = out_path
        self.record = {"steps": [], "selections_sent": 0}  # steps: calls, and in order selections
        self.lock = threading.Lock()
        self.in_flight = {}  # thread id -> (mode, monotonic start)
        threading.Thread(target=self._watch, daemon=True).start()

    def call(self, proxy, mode, **extra):
        """proxy(mode) (a process_mode ServiceProxy) recorded as {mode, success, message, seconds,
        **extra}, or {mode, error, seconds, **extra} when the call raised; returns the entry."""
        import rospy

        me = threading.get_ident()
        with self.lock:
            self.in_flight[me] = (mode, time.monotonic())
        start = time.monotonic()
        try:
            response = proxy(mode)
            entry = {"mode": mode, "success": response.success, "message": response.message}
        except (rospy.ServiceException, rospy.ROSException) as e:
            entry = {"mode": mode, "error": f"{type(e).__name__}: {e}"}
        entry.update(seconds=time.monotonic() - start, **extra)
        with self.lock:
            del self.in_flight[me]
            self.record["steps"].append(entry)
        return entry

    def _watch(self):
        while True:
            time.sleep(0.5)
            with self.lock:
                late = [(mode, time.monotonic() - start) for mode, start in self.in_flight.values()
                        if time.monotonic() - start > CALL_TIMEOUT]
                if late:
                    self.record["unanswered"] = [{"mode": mode, "waited": waited} for mode, waited in late]
                    self._dump()
                    os._exit(3)

    def selected(self, name, acknowledged=None):
        """Counts a selection sent; with acknowledged (points the node stored), records it as a step."""
        with self.lock:
            self.record["selections_sent"] += 1
            if acknowledged is not None:
                self.record["steps"].append({"select": name, "acknowledged": acknowledged})

    def write(self):
        with self.lock:
            self._dump()

    def _dump(self):
        with open(self.out_path, "w") as f:
            json.dump(self.record, f)


def pose_list(pose_msg):
    p, q = pose_msg.pose.position, pose_msg.pose.orientation
    return [p.x, p.y, p.z, q.x, q.y, q.z, q.w]


def send(client, selection, wait):
    """Publishes a selection (points, click: see selection_points); with wait, returns how many
    points the node acknowledged."""
    points, click = selection
    if wait:
        return client.click(click) if click is not None else client.select(points)
    if click is not None:
        from geometry_msgs.msg import PointStamped

        msg = PointStamped()
        msg.header.frame_id = "world"
        msg.point.x, msg.point.y, msg.point.z = click
        client.clicked_pub.publish(msg)
    else:
        from example_pcl.conversions import xyz_to_cloud

        client.selected_pub.publish(xyz_to_cloud(points, frame_id="world"))
    return None


def sequential(recorder, client, selections, calls):
    """SEQUENTIAL_CYCLE until `calls` calls are made; the cycle's patches alternate between the
    rectangles and the clicks. Selections are recorded as steps {select, acknowledged} between
    the calls."""
    import rospy

    from example_pcl.srv import ProcessMode

    proxy = rospy.ServiceProxy(client.service_name, ProcessMode)
    made, cycle = 0, 0
    while True:
        kind = "rect" if cycle % 2 == 0 else "click"
        for step in SEQUENTIAL_CYCLE:
            if isinstance(step, str):
                name = f"{step}_{kind}"
                recorder.selected(name, send(client, selections[name], wait=True))
                continue
            if made == calls:
                return
            poses = client.count("can_pose")
            entry = recorder.call(proxy, step, cycle=cycle)
            made += 1
            if entry.get("success") and step in (2, 3, 4):
                entry["pose"] = pose_list(client.wait_for("can_pose", after=poses))
        cycle += 1


def concurrent(recorder, client, selections, xyz, n_clients, calls_per_client):
    """The storm (see the module docstring), then the clean walkthrough, recorded as "after"."""
    import rospy

    from example_pcl.find_can_client import walkthrough
    from example_pcl.srv import ProcessMode

    stop = threading.Event()

    def publish_selections():
        i = 0
        while not stop.is_set():
            name = STORM_SELECTIONS[i % len(STORM_SELECTIONS)]
            send(client, selections[name], wait=False)
            recorder.selected(name)
            i += 1
            time.sleep(0.02)

    def hammer(index):
        proxy = rospy.ServiceProxy(client.service_name, ProcessMode, persistent=index % 2 == 1)
        rng = random.Random(STORM_SEED + index)
        for _ in range(calls_per_client):
            recorder.call(proxy, rng.choice(STORM_MODES), client=index)
        proxy.close()

    publisher = threading.Thread(target=publish_selections, daemon=True)
    workers = [threading.Thread(target=hammer, args=(i,), daemon=True) for i in range(n_clients)]
    start = time.monotonic()
    publisher.start()
    for worker in workers:
        worker.start()
    for worker in workers:
        worker.join()  # the watchdog ends the run if a call hangs
    stop.set()
    publisher.join()
    recorder.record["storm_seconds"] = time.monotonic() - start
    # The last storm selection on each topic, acknowledged: every earlier one is handled (or dropped).
    for name in ("table_click", "table_near"):
        send(client, selections[name], wait=True)
        recorder.selected(name)
    messages = []
    pose, _, _ = walkthrough(client, xyz, say=messages.append)
    recorder.record["after"] = {"messages": messages, "pose": pose_list(pose)}


def main(argv):
    import rospy

    from find_can_helpers import OperatorClient

    from example_pcl.can_finder import CanFinder, FinderConfig
    from example_pcl.pcd import read_pcd
    from example_pcl.resources import package_path

    kind, numbers, out_path = argv[0], [int(a) for a in argv[1:-1]], argv[-1]
    rospy.init_node("find_can_load_client", anonymous=True)
    xyz = np.ascontiguousarray(read_pcd(package_path("data", "test_pcd.pcd")).xyz)
    finder = CanFinder(xyz, FinderConfig())
    selections = {name: selection_points(name, xyz, finder) for name in SELECTIONS}
    client = OperatorClient(timeout=CALL_TIMEOUT)
    recorder = Recorder(out_path)
    if kind == "sequential":
        sequential(recorder, client, selections, *numbers)
    else:
        concurrent(recorder, client, selections, xyz, *numbers)
    recorder.write()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

"""find_can under load: 1000 process_mode calls in a row, and 4 concurrent clients while selections keep
changing; every call answered, no deadlock, every answer one the pipeline gives, the node up and its log clean.

find_can_load_client.py (a rospy process) makes the calls and records the answers; this file starts
find_can on the bundled scene and checks the record against the pipeline without ROS: a CanFinder
given the same selections and modes (the sequential run), or every answer a CanFinder can give
from any order of the storm's selections and modes (the concurrent run).
"""
import collections
import copy
import functools
import json
import pathlib
import re
import subprocess
import sys

import numpy as np
import pytest

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import find_can_load_client as load  # noqa: E402

CLIENT = str(pathlib.Path(__file__).resolve().parent / "find_can_load_client.py")
SEQUENTIAL_CALLS = 1000
CLIENTS, CALLS_PER_CLIENT = 4, 150
pytestmark = pytest.mark.skipif(subprocess.run(["which", "roscore"], capture_output=True).returncode != 0,
                                reason="roscore missing: run `make test`, which installs ROS")


@functools.lru_cache(maxsize=None)
def bundled_scene():
    """The bundled scene's organized xyz (float32 (H, W, 3)) and its ground truth (the can)."""
    from example_pcl.resources import package_path
    from example_pcl.pcd import read_pcd

    xyz = np.ascontiguousarray(read_pcd(package_path("data", "test_pcd.pcd")).xyz)
    xyz.flags.writeable = False
    truth = json.loads(pathlib.Path(package_path("data", "test_pcd.json")).read_text())["cans"][0]
    return xyz, truth


def fresh_finder():
    from example_pcl.can_finder import CanFinder, FinderConfig

    return CanFinder(bundled_scene()[0], FinderConfig())


@functools.lru_cache(maxsize=None)
def patch(name):
    """The points find_can stores for a named selection of find_can_load_client (float32 (K, 3))."""
    return load.selection_points(name, bundled_scene()[0], fresh_finder())[0]


def normalized(message):
    """A message without what may differ between runs: mode 4's timing."""
    return re.sub(r"\(\d+ ms\)", "(… ms)", message)


def answer(finder, mode):
    """What find_can answers to process_mode(mode) in the finder's state: (success, message,
    T_sensor_from_can or None), as FindCanNode.on_process_mode words it (frame world)."""
    from example_pcl.errors import PerceptionError

    try:
        result = finder.process(mode)
    except PerceptionError as e:
        return False, str(e), None
    if result.can is None:
        return True, result.message, None
    return True, result.message + " (frame world)", result.can.T_sensor_from_can


def pose_difference(pose, T):
    """(position difference in m, quaternion difference) of a recorded can_pose [x, y, z, qx, qy, qz, qw] and a 4x4."""
    from example_pcl.transforms import quaternion_xyzw_from_matrix

    pose = np.asarray(pose)
    return float(np.abs(pose[:3] - T[:3, 3]).max()), float(np.abs(pose[3:] - quaternion_xyzw_from_matrix(T[:3, :3])).max())


def run_load(ros_graph, tmp_path, *args):
    """find_can on the bundled scene, find_can_load_client with args; returns (record, node log) once
    the node, still running, is stopped with SIGINT and has exited cleanly."""
    node = ros_graph.rosrun("find_can", "find_can")
    out = tmp_path / "record.json"
    client = subprocess.run([sys.executable, CLIENT, *map(str, args), str(out)], env=ros_graph.env, cwd=tmp_path,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=600)
    record = json.loads(out.read_text()) if out.exists() else {}
    assert not record.get("unanswered"), f"calls unanswered after {load.CALL_TIMEOUT} s: {record['unanswered']}"
    assert client.returncode == 0, client.stdout[-4000:]
    assert node.poll() is None, "find_can died:\n" + ros_graph.log(node)[-4000:]
    assert ros_graph.stop(node) == 0, ros_graph.log(node)[-4000:]
    log = ros_graph.log(node)
    bad = [line[:300] for line in log.splitlines() if "Traceback" in line or "[ERROR]" in line or "[FATAL]" in line]
    assert not bad, f"{len(bad)} error lines in find_can's log, the first:\n" + "\n".join(bad[:5])
    return record, log


def vague_refusals(calls):
    """The refusals among the recorded calls that do not say what to do next."""
    return [c["message"] for c in calls
            if not c["success"] and not re.search(r"select|call mode|unknown mode", c["message"])]


def test_1000_calls_in_a_row_are_answered_as_the_pipeline_answers(ros_graph, tmp_path):
    """1000 calls in a row are each answered as CanFinder answers the same steps; each walkthrough, the same pose."""
    # The calls: walkthroughs by rectangles and by clicks in turn, out-of-order calls, mode 3 again,
    # mode 4 and modes 1 and 3 after it, an unknown mode (find_can_load_client.SEQUENTIAL_CYCLE).
    # Each answer must carry exactly the success, message and can pose (1e-9) of a CanFinder given
    # the same selections and modes; every refusal must say what to do next.
    record, _ = run_load(ros_graph, tmp_path, "sequential", SEQUENTIAL_CALLS)
    calls = [step for step in record["steps"] if "mode" in step]
    assert len(calls) == SEQUENTIAL_CALLS
    assert not [c for c in calls if "error" in c], [c for c in calls if "error" in c][:5]

    finder, mismatches = fresh_finder(), []
    fits = collections.defaultdict(list)  # selection kind -> poses of the mode 3 right after mode 2
    previous_mode = None
    for i, step in enumerate(record["steps"]):
        if "select" in step:
            stored = finder.select(patch(step["select"]))
            if stored != step["acknowledged"]:
                mismatches.append((i, step["select"], f"{step['acknowledged']} points acknowledged, not {stored}"))
            continue
        success, message, T = answer(finder, step["mode"])
        if (step["success"], normalized(step["message"])) != (success, normalized(message)):
            mismatches.append((i, step["mode"], step["message"], message))
        elif T is not None:
            position, rotation = pose_difference(step["pose"], T)
            if position > 1e-9 or rotation > 1e-9:
                mismatches.append((i, step["mode"], "pose off the pipeline's by", position, rotation))
            if step["mode"] == 3 and previous_mode == 2:
                fits["rect" if step["cycle"] % 2 == 0 else "click"].append(np.asarray(step["pose"]))
        previous_mode = step["mode"]
    assert not mismatches, mismatches[:5]

    truth = np.asarray(bundled_scene()[1]["base_center"])
    assert set(fits) == {"rect", "click"}, fits.keys()
    for kind, poses in fits.items():
        assert len(poses) >= 30, (kind, len(poses))
        np.testing.assert_allclose(poses, np.broadcast_to(poses[0], np.shape(poses)), rtol=0, atol=1e-9)
        assert np.linalg.norm(poses[0][:3] - truth) < 3e-3, (kind, poses[0])
    refusals = [c["message"] for c in calls if not c["success"]]
    assert len(refusals) > SEQUENTIAL_CALLS // 3
    assert not vague_refusals(calls), vague_refusals(calls)[:5]
    print(f"\nsequential: {len(calls)} calls, {len(refusals)} refused (out of order, unknown mode), "
          f"{record['selections_sent']} selections; slowest answer {max(c['seconds'] for c in calls):.2f} s")


def reachable_answers(selections, modes):
    """Every answer find_can can give, by mode: the set of (success, normalized message) over every
    state a CanFinder on the bundled scene reaches from a fresh one through any sequence of the
    named selections and the modes (breadth-first over exact states; a few hundred).

    Modes 0 and 4 start afresh: what they answer and the state they leave depend on the latest
    selection only (mode 0 fits it, mode 4 needs none, both forget the rest), so each is run once
    per latest selection and its outcome reused.
    """
    def state(finder, selected):
        def exact(a):
            return None if a is None else np.asarray(a).tobytes()

        can = finder.can
        return (selected, finder.has_can_patch, exact(finder.T_sensor_from_plane), finder.above_indices is None,
                None if can is None else exact(can.T_sensor_from_can) + exact(can.center_plane))

    points = {name: patch(name) for name in selections}
    answers = collections.defaultdict(set)
    afresh = {}  # (mode 0 or 4, latest selection) -> (success, message, the finder after it or None)
    start = (fresh_finder(), None)
    seen, frontier = {state(*start)}, [start]
    while frontier:
        following = []
        for finder, selected in frontier:
            for op in [*selections, *modes]:
                # A shallow copy is a separate state: CanFinder replaces its arrays, never writes into them.
                nxt, now = copy.copy(finder), selected
                if op in points:
                    nxt.select(points[op])
                    now = op
                elif op in (0, 4):
                    if (op, selected) not in afresh:
                        success, message, _ = answer(nxt, op)
                        afresh[op, selected] = success, message, nxt if success else None
                    success, message, after = afresh[op, selected]
                    nxt = copy.copy(after) if success else nxt
                    answers[op].add((success, normalized(message)))
                else:
                    success, message, _ = answer(nxt, op)
                    answers[op].add((success, normalized(message)))
                key = state(nxt, now)
                if key not in seen:
                    seen.add(key)
                    following.append((nxt, now))
        frontier = following
    return answers


def test_4_concurrent_clients_while_selections_change(ros_graph, tmp_path):
    """4 concurrent clients while selections change: every call answered, each answer one find_can gives in order."""
    # 4 clients (a ServiceProxy each, 2 of them persistent) make 150 calls each of modes 0-5 at once
    # while selections alternate between the table and the can on selected_points and clicked_point.
    # Every answer must be one a CanFinder gives in some order of the same requests, every mode 0-4
    # must succeed at least once, and a clean walkthrough afterwards must give the pipeline's
    # messages and pose.
    record, log = run_load(ros_graph, tmp_path, "concurrent", CLIENTS, CALLS_PER_CLIENT)
    calls = record["steps"]
    assert collections.Counter(c["client"] for c in calls) == {i: CALLS_PER_CLIENT for i in range(CLIENTS)}
    assert not [c for c in calls if "error" in c], [c for c in calls if "error" in c][:5]

    # The table patch and the can patch, whichever topic brought them.
    reachable = reachable_answers(("table_near", "can_near"), sorted(set(load.STORM_MODES)))
    unexpected = [(c["mode"], c["message"]) for c in calls
                  if (c["success"], normalized(c["message"])) not in reachable[c["mode"]]]
    assert not unexpected, unexpected[:5]
    assert not vague_refusals(calls), vague_refusals(calls)[:5]
    succeeded = collections.Counter(c["mode"] for c in calls if c["success"])
    assert all(succeeded[mode] > 0 for mode in range(5)), succeeded

    finder, expected = fresh_finder(), []
    for step in ("table_rect", 0, 1, "can_rect", 2, 3):
        if isinstance(step, str):
            finder.select(patch(step))
            continue
        _, message, T = answer(finder, step)
        expected.append(message)
    got = [m.split(": ", 1)[1] for m in record["after"]["messages"] if m.lstrip().startswith("mode")]
    assert got == expected
    position, rotation = pose_difference(record["after"]["pose"], T)
    assert position < 1e-9 and rotation < 1e-9, (position, rotation)

    taken = sum(1 for line in log.splitlines() if "find_can: selection of" in line or "find_can: clicked (" in line)
    assert taken > 10, "the selections did not reach find_can during the storm"
    print(f"\nconcurrent: {len(calls)} calls from {CLIENTS} clients in {record['storm_seconds']:.1f} s, "
          f"{record['selections_sent']} selections sent, {taken} taken; successes by mode "
          f"{dict(sorted(succeeded.items()))}; slowest answer {max(c['seconds'] for c in calls):.2f} s")

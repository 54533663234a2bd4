"""The seed's walkthrough, headless: ``make demo`` runs it against a running find_can.

``python3 -m example_pcl.demo [--pcd SCENE.pcd] [--out PICTURE.png]`` (tools/demo.sh starts
``find_can.launch rviz:=false`` first) plays the operator of
:func:`example_pcl.find_can_client.walkthrough` (table patch, modes 0 and 1, can patch, modes 2
and 3), printing each step's message; then prints the can's pose with its error against the
scene's ground truth (the .json beside the .pcd) and writes a picture of the result (the scene's
depth coloured by z, the table's inliers, the registered can model).
"""
import argparse
import json
import os
import pathlib
import sys
import time

import numpy as np

from example_pcl import scene as scene_module
from example_pcl.errors import PerceptionError


def write_picture(path, xyz, plane_points, model_points, title=""):
    """A PNG of the result: the organized scene's depth coloured by z (m), the table's inliers
    tinted, the registered model's points projected with the simulated Kinect's intrinsics."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    def project(points):
        pts = np.asarray(points, dtype=float).reshape(-1, 3)
        pts = pts[np.isfinite(pts).all(axis=1) & (pts[:, 2] > 0)]
        return (scene_module.FX * pts[:, 0] / pts[:, 2] + scene_module.CX,
                scene_module.FY * pts[:, 1] / pts[:, 2] + scene_module.CY)

    height, width = xyz.shape[:2]
    fig, ax = plt.subplots(figsize=(9, 6.75), dpi=100)
    image = ax.imshow(xyz[..., 2], cmap="viridis", interpolation="nearest")
    fig.colorbar(image, ax=ax, fraction=0.035, label="z (m, sensor frame)")
    if plane_points is not None and len(plane_points):
        u, v = project(plane_points)
        overlay = np.zeros((height, width, 4))
        inside = (u >= -0.5) & (u < width - 0.5) & (v >= -0.5) & (v < height - 0.5)
        overlay[np.round(v[inside]).astype(int), np.round(u[inside]).astype(int)] = (1.0, 0.55, 0.0, 0.45)
        ax.imshow(overlay, interpolation="nearest")
    if model_points is not None and len(model_points):
        u, v = project(model_points)
        ax.plot(u, v, ",", color="red", label="registered can model")
        ax.legend(loc="upper right")
    ax.set_xlim(-0.5, width - 0.5)
    ax.set_ylim(height - 0.5, -0.5)
    ax.set_title(title or "find_can: scene (z), table inliers (orange), registered can (red)", fontsize=9)
    ax.set_xlabel("u (px)")
    ax.set_ylabel("v (px)")
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, bbox_inches="tight")
    plt.close(fig)
    return path


def main(argv=None):
    """``python3 -m example_pcl.demo [--pcd F] [--out PNG]``: the walkthrough; returns the exit status."""
    from example_pcl.resources import default_scene_path

    parser = argparse.ArgumentParser(prog="find_can demo", description=__doc__.split("\n\n")[0])
    parser.add_argument("--pcd", default=default_scene_path(), help="the scene find_can loaded (default: the "
                        "package's bundled scene)")
    parser.add_argument("--out", default="find_can_demo.png", help="picture to write (default: %(default)s in the "
                        "current directory)")
    parser.add_argument("--timeout", type=float, default=30.0, help="s to wait for the node and each reply")
    args = parser.parse_args(argv)

    import rospy

    from example_pcl.find_can_client import FindCanClient, walkthrough
    from example_pcl.messages import matrix_from_pose
    from example_pcl.pcd import read_pcd

    rospy.init_node("find_can_demo", anonymous=True, disable_signals=False)
    start = time.monotonic()
    try:
        xyz = np.ascontiguousarray(read_pcd(args.pcd).xyz)
        print(f"find_can demo on {args.pcd}:")
        client = FindCanClient(timeout=args.timeout)
        pose, plane, model = walkthrough(client, xyz)
    except (PerceptionError, rospy.ROSException) as e:
        print(f"demo failed: {e}", file=sys.stderr)
        return 1
    p, q = pose.pose.position, pose.pose.orientation
    print(f"can pose in '{pose.header.frame_id}': position ({p.x:.4f}, {p.y:.4f}, {p.z:.4f}) m, "
          f"orientation (x, y, z, w) ({q.x:.4f}, {q.y:.4f}, {q.z:.4f}, {q.w:.4f})")
    truth_file = scene_module.truth_path(args.pcd)
    title = ""
    if truth_file.is_file():
        truth = json.loads(truth_file.read_text())
        centre, axis = scene_module.can_pose_error(matrix_from_pose(pose.pose), truth["cans"][0])
        title = f"find_can: centre error {centre * 1e3:.2f} mm, axis error {axis:.2f} deg"
        print(f"error against the ground truth ({truth_file.name}): centre {centre * 1e3:.2f} mm, axis {axis:.2f} deg")
    out = write_picture(args.out, xyz, plane, model, title)
    print(f"picture written to {os.path.relpath(out)} ({time.monotonic() - start:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())

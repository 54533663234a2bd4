"""The operator's workflow in a real rviz window (Xvfb, software rendering), driven with xdotool.

One rviz, started by ``roslaunch example_pcl find_can.launch rviz:=true`` on a private master and
a private X display, serves the module. The tests check what is drawn in the 3-D view against
where the bundled scene's points project (rviz's Orbit camera, rviz_driver.OrbitView), then work
the seed's walkthrough with the mouse: the Publish Selection tool (this package's rviz plugin)
dragged over the table and over the can, and once the stock Publish Point tool; the service calls
are `rosservice call` as docs/walkthrough.md documents, and the can pose that comes out is compared
with the scene's ground truth.

With EXAMPLE_PCL_SCREENSHOTS=DIR (``make screenshots``) each step's view is saved to DIR as PNG:
the pictures of docs/walkthrough.md.
"""
import colorsys
import json
import os
import pathlib
import subprocess
import sys
import time

import numpy as np
import pytest
import yaml

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from find_can_helpers import pose_error  # noqa: E402
from graph_helpers import RosGraph, wait_for  # noqa: E402
from rviz_driver import OrbitView, RvizWindow, Xvfb, missing_tools, near_colour, pixel_mask, saturated  # noqa: E402

from example_pcl.conversions import cloud_to_xyz  # noqa: E402
from example_pcl.find_can_client import CAN_RECT, TABLE_RECT  # noqa: E402
from example_pcl.pcd import read_pcd  # noqa: E402

PROJECT = pathlib.Path(__file__).resolve().parents[2]
SCENE = PROJECT / "data" / "test_pcd.pcd"
RVIZ_CONFIG = PROJECT / "rviz" / "find_can.rviz"
PLANE_COLOUR = (255, 255, 255)  # plane_model's flat colour in rviz/find_can.rviz
SELECTION_COLOUR = (0, 255, 255)  # rviz's highlight of selected points
# The walkthrough in rviz must do as well as the scripted one (issue 4's figure: within 3 mm).
MAX_CENTRE_ERROR = 0.003  # m
MAX_AXIS_ERROR = 2.0  # degrees

pytestmark = pytest.mark.skipif(bool(missing_tools()) or subprocess.run(["which", "roscore"], capture_output=True)
                                .returncode != 0,
                                reason=f"needs {', '.join(missing_tools()) or 'roscore'} on PATH: `make test` "
                                       "installs Xvfb, xdotool, x11-utils, rviz and ROS (tools/setup.sh)")


class Operator:
    """rviz with find_can behind it, and the scene's ground truth to aim the mouse with."""

    def __init__(self, tmp_path):
        self.shots = pathlib.Path(os.environ["EXAMPLE_PCL_SCREENSHOTS"]) if os.environ.get(
            "EXAMPLE_PCL_SCREENSHOTS") else None
        self.xvfb = Xvfb()
        self.graph = RosGraph(tmp_path)
        self.graph.env["DISPLAY"] = self.xvfb.display
        self.launch = self.graph.start("find_can_launch", ["roslaunch", "example_pcl", "find_can.launch", "rviz:=true"])
        self.window = RvizWindow(self.xvfb.display, timeout=120)
        self.view = OrbitView.from_rviz_config(RVIZ_CONFIG)
        self.organized = read_pcd(SCENE).xyz
        xyz = self.organized.reshape(-1, 3)
        self.points = xyz[np.isfinite(xyz).all(axis=1)]
        self.truth = json.loads(SCENE.with_suffix(".json").read_text())

    def close(self):
        self.graph.close()
        self.xvfb.close()

    def log(self):
        return self.graph.log(self.launch)

    def image(self):
        return self.window.view_image()

    def project(self, points):
        """Pixels (u, v, visible) of the points in the 3-D view as it is now sized."""
        _, _, width, height = self.window.render_panel()
        return self.view.project(points, width, height)

    def wait_drawn(self, predicate, timeout=60):
        """The view once predicate(image) holds (rviz renders at its own pace under Xvfb)."""
        image = None

        def drawn():
            nonlocal image
            image = self.image()
            return predicate(image)

        assert wait_for(drawn, timeout, step=0.5), f"rviz did not draw it within {timeout} s; rviz/find_can log:\n{self.log()}"
        return image

    def save(self, image, name):
        """With EXAMPLE_PCL_SCREENSHOTS set, the view as DIR/name.jpg at half size (docs/rviz/)."""
        if self.shots is not None:
            from PIL import Image

            self.shots.mkdir(parents=True, exist_ok=True)
            picture = Image.fromarray(image)
            picture.resize((picture.width // 2, picture.height // 2), Image.LANCZOS).save(
                self.shots / f"{name}.jpg", quality=85)

    def wait_changed(self, before, timeout=60):
        """The view once rviz has drawn something new (at least 1000 pixels differ from `before`)."""
        self.wait_drawn(lambda im: (np.abs(im.astype(np.int16) - before).max(axis=2) > 60).sum() > 1000, timeout)
        time.sleep(1.0)  # the rest of the step's topics (marker, pose) arrive within a frame or two
        return self.image()

    def echo(self, topic, msg_class):
        """The message a subscriber connecting now gets on a latched topic (`rostopic echo -n 1`)."""
        import genpy

        out = subprocess.run(["rostopic", "echo", "-n", "1", topic], env=self.graph.env, capture_output=True,
                             text=True, timeout=30)
        msg = msg_class()
        genpy.message.fill_message_args(msg, [yaml.safe_load(out.stdout.split("---")[0])])
        return msg

    def selected_points(self):
        """The last cloud the Publish Selection tool sent (latched on /selected_points), (N, 3) metres."""
        from sensor_msgs.msg import PointCloud2

        msg = self.echo("/selected_points", PointCloud2)
        assert msg.header.frame_id == "world", msg.header
        assert [(f.name, f.datatype) for f in msg.fields] == [("x", 7), ("y", 7), ("z", 7)], msg.fields
        return cloud_to_xyz(msg).reshape(-1, 3).astype(float)

    def patch(self, rect):
        """The scene's points in a pixel rectangle (u0, v0, u1, v1) of the organized cloud."""
        u0, v0, u1, v1 = rect
        pts = self.organized[v0:v1 + 1, u0:u1 + 1].reshape(-1, 3)
        return pts[np.isfinite(pts).all(axis=1)]

    def screen_rect(self, points, shrink=0.25):
        """The rectangle of the view (u0, v0, u1, v1) the points project into, shrunk toward its centre
        so that the drag stays inside the patch."""
        u, v, visible = self.project(points)
        assert visible.all(), "the patch is not in rviz's view"
        u0, u1, v0, v1 = u.min(), u.max(), v.min(), v.max()
        du, dv = shrink * (u1 - u0), shrink * (v1 - v0)
        return u0 + du, v0 + dv, u1 - du, v1 - dv

    def screen_point(self, points):
        """The pixel of the patch's point nearest its centroid (a point that is really there to click)."""
        point = points[np.argmin(np.linalg.norm(points - points.mean(axis=0), axis=1))]
        u, v, visible = self.project(point[None])
        assert visible[0]
        return u[0], v[0]

    def selections(self):
        """How many selections find_can has stored so far (its log lines)."""
        log = self.log()
        return log.count("find_can: selection of") + log.count("find_can: clicked (")

    def use_tool(self, key):
        """Focus the 3-D view and press a tool's shortcut key. Escape first: it brings back the default
        tool, while a selection tool (Select, Publish Selection) keeps the other keys for itself."""
        self.window.focus_view()
        self.window.key("Escape")
        self.window.key(key)
        time.sleep(0.5)

    def select_rect(self, points):
        """Drags the active tool over the points' screen rectangle; returns find_can's log line."""
        before = self.selections()
        self.window.drag(*self.screen_rect(points))
        assert wait_for(lambda: self.selections() > before, 30), f"find_can got no selection:\n{self.log()}"
        return self.log().splitlines()[-1]

    def click_point(self, points):
        before = self.selections()
        self.window.click(*self.screen_point(points))
        assert wait_for(lambda: self.selections() > before, 30), f"find_can got no clicked point:\n{self.log()}"

    def process_mode(self, mode):
        """`rosservice call /process_mode N`, as docs/walkthrough.md says; the answer as a dict."""
        out = subprocess.run(["rosservice", "call", "/process_mode", str(mode)], env=self.graph.env,
                             capture_output=True, text=True, timeout=60)
        assert out.returncode == 0, out.stdout + out.stderr
        answer = yaml.safe_load(out.stdout)
        assert answer["success"], f"mode {mode}: {answer['message']}"
        return answer

    def can_pose(self):
        """The latched can_pose, as a geometry_msgs/PoseStamped."""
        from geometry_msgs.msg import PoseStamped

        return self.echo("/can_pose", PoseStamped)


@pytest.fixture(scope="module")
def operator(tmp_path_factory):
    op = Operator(tmp_path_factory.mktemp("rviz"))
    yield op
    op.close()


def _hue(image, u, v):
    """Hue in [0, 1) of the view's pixels at (u, v)."""
    rgb = image[np.round(v).astype(int), np.round(u).astype(int)] / 255.0
    return np.array([colorsys.rgb_to_hsv(*c)[0] for c in rgb])


def test_scene_is_drawn_where_it_projects_coloured_by_depth(operator):
    """The scene's points are drawn (saturated colour) where rviz's camera projects them, and nowhere
    else; their colour runs through the rainbow with depth (z, metres): red near, blue far."""
    image = operator.wait_drawn(lambda im: saturated(im).mean() > 0.2)
    operator.save(image, "1_scene")
    u, v, visible = operator.project(operator.points)
    assert visible.mean() > 0.95, "rviz's view should frame the whole scene"
    drawn = saturated(image)
    expected = pixel_mask(u, v, visible, image.shape[:2], grow=2)
    at_points = drawn[np.round(v[visible]).astype(int), np.round(u[visible]).astype(int)]
    assert at_points.mean() > 0.9, f"only {at_points.mean():.0%} of the scene's pixels are drawn"
    assert (drawn & ~expected).sum() < 0.01 * drawn.sum(), "points drawn where the scene is not"
    # Colour by z: rviz's AxisColor rainbow goes from red (nearest) to blue/magenta (farthest).
    sample = np.random.default_rng(0).choice(np.flatnonzero(visible), 3000, replace=False)
    hue = _hue(image, u[sample], v[sample])
    z = operator.points[sample, 2]
    rank_corr = np.corrcoef(np.argsort(np.argsort(hue)), np.argsort(np.argsort(z)))[0, 1]
    assert rank_corr > 0.8, f"the colour does not follow depth (rank correlation {rank_corr:.2f})"


def test_walkthrough_with_the_publish_selection_tool(operator):
    """The seed's workflow with the mouse: Publish Selection dragged over the table, modes 0 and 1 (the
    plane's points drawn in plane_model's colour on the table), dragged over the can, modes 2 and 3:
    the can's pose within 3 mm and 2 degrees of the ground truth."""
    table, can = operator.patch(TABLE_RECT), operator.patch(CAN_RECT)
    operator.use_tool("l")
    line = operator.select_rect(table)
    assert "selection of" in line, line
    n_selected = int(line.split("selection of ")[1].split()[0])
    assert n_selected >= 20, line
    # The tool sends the scene's own points (not positions read off the screen), those in the rectangle.
    selected = operator.selected_points()
    assert len(selected) == n_selected
    nearest = np.array([np.min(np.linalg.norm(operator.points - p, axis=1)) for p in selected])
    assert nearest.max() < 1e-5, f"selected points off the scene by up to {nearest.max() * 1e3:.3f} mm"
    u, v, _ = operator.project(selected)
    u0, v0, u1, v1 = operator.screen_rect(table)
    assert ((u > u0 - 3) & (u < u1 + 3) & (v > v0 - 3) & (v < v1 + 3)).all(), "selected points outside the drag"
    # rviz highlights what it selected in cyan: there, on the table patch.
    u0, v0, u1, v1 = (int(round(c)) for c in operator.screen_rect(table))
    image = operator.wait_drawn(lambda im: near_colour(im[v0:v1, u0:u1], SELECTION_COLOUR, 40).mean() > 0.5)
    operator.save(image, "2_selected_patch")

    operator.process_mode(0)
    image = operator.wait_drawn(lambda im: near_colour(im, PLANE_COLOUR, 30).sum() > 20000)
    operator.save(image, "3_plane")
    plane = near_colour(image, PLANE_COLOUR, 30)
    table_points = operator.points[np.abs(operator.points @ np.array(operator.truth["table"]["normal"])
                                          + operator.truth["table"]["d"]) < 0.01]
    u, v, visible = operator.project(table_points)
    on_table = pixel_mask(u, v, visible, image.shape[:2], grow=3)
    assert (plane & ~on_table).sum() < 0.02 * plane.sum(), "plane_model drawn off the table"

    operator.process_mode(1)
    image = operator.wait_drawn(lambda im: near_colour(im, PLANE_COLOUR, 30).sum() < 0.5 * plane.sum())
    operator.save(image, "4_points_above")
    operator.select_rect(can)
    operator.process_mode(2)
    image = operator.wait_changed(image)
    operator.save(image, "5_first_guess")
    operator.process_mode(3)
    operator.save(operator.wait_changed(image), "6_registered")
    centre, axis = pose_error(operator.can_pose(), operator.truth["cans"][0])
    assert centre < MAX_CENTRE_ERROR and axis < MAX_AXIS_ERROR, f"centre {centre * 1e3:.2f} mm, axis {axis:.2f} deg"


def test_walkthrough_with_the_stock_publish_point_tool(operator):
    """The same with rviz's own Publish Point (clicked_point): a click on the table, modes 0 and 1, a
    click on the can's side, modes 2 and 3: the same pose."""
    operator.use_tool("c")
    operator.click_point(operator.patch(TABLE_RECT))
    assert "clicked (" in operator.log().splitlines()[-1]
    operator.process_mode(0)
    operator.process_mode(1)
    operator.use_tool("c")  # Publish Point in single-click mode hands back to Interact after each click
    operator.click_point(operator.patch(CAN_RECT))
    operator.process_mode(2)
    operator.process_mode(3)
    time.sleep(1.0)
    centre, axis = pose_error(operator.can_pose(), operator.truth["cans"][0])
    assert centre < MAX_CENTRE_ERROR and axis < MAX_AXIS_ERROR, f"centre {centre * 1e3:.2f} mm, axis {axis:.2f} deg"

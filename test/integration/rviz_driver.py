"""Drives a real rviz the way an operator does: an X server (Xvfb), screenshots, the 3-D view's
projection, and the mouse and keyboard through xdotool.

Nothing here knows find_can: the tests in test_rviz_operator.py combine it with the scene's ground
truth. The projection reproduces rviz's Orbit view controller (its position from distance, yaw and
pitch around the focal point; Ogre's look-at with a fixed yaw axis; a perspective of the view's
vertical field of view), so a 3-D point of the scene maps to the pixel it is drawn at.
"""
import os
import shutil
import subprocess
import time

import numpy as np
import yaml
from graph_helpers import wait_for

TOOLS = ("Xvfb", "xdotool", "xwininfo", "rviz")


def missing_tools():
    """The programs the rviz tests need that are not on PATH (tools/setup.sh installs them)."""
    return [tool for tool in TOOLS if shutil.which(tool) is None]


class Xvfb:
    """A virtual X server on a free display number, 24-bit colour; rviz draws into it with Mesa."""

    def __init__(self, width=1600, height=1000):
        read_fd, write_fd = os.pipe()
        # -displayfd: the server picks a free display and writes its number once it accepts clients.
        self.process = subprocess.Popen(["Xvfb", "-displayfd", str(write_fd), "-screen", "0", f"{width}x{height}x24",
                                         "-nolisten", "tcp"], pass_fds=(write_fd,), stdout=subprocess.DEVNULL,
                                        stderr=subprocess.DEVNULL, start_new_session=True)
        os.close(write_fd)
        with os.fdopen(read_fd) as pipe:
            number = pipe.readline().strip()
        if not number:
            self.process.kill()
            raise RuntimeError("Xvfb did not start")
        self.display = f":{number}"

    def close(self):
        self.process.terminate()
        try:
            self.process.wait(10)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()


def screenshot(display):
    """The whole screen of `display` as an (H, W, 3) uint8 array."""
    from PIL import ImageGrab

    return np.asarray(ImageGrab.grab(xdisplay=display).convert("RGB"))


class OrbitView:
    """rviz's Orbit view controller as a pinhole camera (rviz/default_plugin/view_controllers)."""

    def __init__(self, focal_point, distance, yaw, pitch, fov, invert_z=False):
        self.focal_point = np.asarray(focal_point, dtype=float)
        if invert_z:
            yaw, pitch = -yaw, -pitch
        self.up = np.array([0.0, 0.0, -1.0 if invert_z else 1.0])
        self.position = self.focal_point + distance * np.array(
            [np.cos(yaw) * np.cos(pitch), np.sin(yaw) * np.cos(pitch), np.sin(pitch)])
        self.fov = fov

    @classmethod
    def from_rviz_config(cls, path):
        """The 'Current' view of an .rviz file (an Orbit view in the fixed frame)."""
        view = yaml.safe_load(open(path))["Visualization Manager"]["Views"]["Current"]
        if view["Class"] != "rviz/Orbit":
            raise ValueError(f"{path}: the current view is {view['Class']}, not rviz/Orbit")
        focal = view["Focal Point"]
        return cls((focal["X"], focal["Y"], focal["Z"]), view["Distance"], view["Yaw"], view["Pitch"],
                   view.get("Field of View", 0.785398), view.get("Invert Z Axis", False))

    def project(self, points, width, height):
        """Pixels (u right, v down, from the 3-D view's top-left corner) of (N, 3) points in the fixed
        frame (metres), as float arrays u, v, and whether each is in front of the camera and in the view."""
        forward = self.focal_point - self.position
        forward /= np.linalg.norm(forward)
        # Ogre's setDirection with a fixed yaw axis: right = yaw_axis x backward, up = backward x right.
        backward = -forward
        right = np.cross(self.up, backward)
        right /= np.linalg.norm(right)
        up = np.cross(backward, right)
        rel = np.asarray(points, dtype=float).reshape(-1, 3) - self.position
        x, y, depth = rel @ right, rel @ up, rel @ forward
        focal_px = (height / 2.0) / np.tan(self.fov / 2.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            u = width / 2.0 + focal_px * x / depth
            v = height / 2.0 - focal_px * y / depth
        visible = (depth > 0) & (u >= 0) & (u < width) & (v >= 0) & (v < height)
        return u, v, visible


def _xdotool(display, *args, timeout=30):
    env = dict(os.environ, DISPLAY=display)
    return subprocess.run(["xdotool", *map(str, args)], env=env, capture_output=True, text=True, timeout=timeout,
                          check=True).stdout


class RvizWindow:
    """The rviz main window on an X display: where its 3-D view is, screenshots of it, mouse and keys."""

    def __init__(self, display, title="RViz", timeout=60):
        self.display = display
        ids = []

        def shown():
            nonlocal ids
            try:
                ids = _xdotool(display, "search", "--onlyvisible", "--name", title, timeout=10).split()
            except subprocess.CalledProcessError:  # xdotool: no such window yet
                ids = []
            return bool(ids)

        if not wait_for(shown, timeout, step=0.5):
            raise TimeoutError(f"no visible window titled '{title}' on {display} after {timeout} s")
        self.window = ids[0]

    def render_panel(self):
        """(x, y, width, height) on the screen of the 3-D view. Ogre renders into a native X window inside
        the view's frame (which adds the docks' collapse buttons at its sides): the deepest of the windows
        nearly as large as the largest one inside rviz's (the docks and tool bars are much smaller)."""
        env = dict(os.environ, DISPLAY=self.display)
        tree = subprocess.run(["xwininfo", "-tree", "-id", self.window], env=env, capture_output=True, text=True,
                              timeout=10, check=True).stdout
        windows = []
        for line in tree.splitlines()[1:]:
            parts = line.split()
            if len(parts) < 2 or not parts[0].startswith("0x"):
                continue
            geometry, absolute = parts[-2], parts[-1]  # "WxH+x+y" relative to the parent, "+X+Y" on the screen
            try:
                w, h = (int(n) for n in geometry.split("+")[0].split("x"))
                x, y = (int(n) for n in absolute.lstrip("+").split("+"))
            except ValueError:
                continue
            windows.append((x, y, w, h))
        if not windows:
            raise RuntimeError(f"no child window in rviz's window:\n{tree}")
        largest = max(w * h for _, _, w, h in windows)
        return min((win for win in windows if win[2] * win[3] >= 0.9 * largest), key=lambda win: win[2] * win[3])

    def view_image(self):
        """A screenshot of the 3-D view alone."""
        x, y, w, h = self.render_panel()
        return screenshot(self.display)[y:y + h, x:x + w]

    def key(self, *keys):
        _xdotool(self.display, "key", *keys)

    def click(self, u, v, button=1):
        """A click (1 left, 2 middle) at pixel (u, v) of the 3-D view."""
        x, y, _, _ = self.render_panel()
        _xdotool(self.display, "mousemove", int(x + u), int(y + v))
        # rviz hands mouse events to the tool at its next update (30 Hz, slower under load): let the
        # tool see the pointer arrive before the button goes down, as under a hand.
        time.sleep(1.0)
        _xdotool(self.display, "click", button)

    def focus_view(self):
        """Gives the 3-D view the keyboard focus (tool shortcuts go there) with a middle click, which no
        tool of ours acts on and which moves the Orbit camera only when dragged."""
        self.click(5, 5, button=2)

    def drag(self, u0, v0, u1, v1, steps=12):
        """A left-button drag from (u0, v0) to (u1, v1) in the 3-D view, moved in steps as a hand would,
        so rviz sees the press, the motion and the release."""
        x, y, _, _ = self.render_panel()
        _xdotool(self.display, "mousemove", int(x + u0), int(y + v0))
        time.sleep(0.2)
        _xdotool(self.display, "mousedown", 1)
        for t in np.linspace(0.0, 1.0, steps)[1:]:
            _xdotool(self.display, "mousemove", int(x + u0 + t * (u1 - u0)), int(y + v0 + t * (v1 - v0)))
            time.sleep(0.03)
        time.sleep(0.2)
        _xdotool(self.display, "mouseup", 1)


def saturated(image, min_chroma=60):
    """Pixels of a saturated colour (a point coloured by the rainbow or a flat colour), as a bool mask:
    the background, the grid and the widgets are greys."""
    image = image.astype(np.int16)
    return (image.max(axis=2) - image.min(axis=2)) >= min_chroma


def near_colour(image, rgb, tolerance=40):
    """Pixels within `tolerance` (per channel) of the colour rgb, as a bool mask."""
    return (np.abs(image.astype(np.int16) - np.asarray(rgb, dtype=np.int16)) <= tolerance).all(axis=2)


def pixel_mask(u, v, visible, shape, grow=0):
    """A bool mask of the pixels points project to (grown by `grow` pixels in each direction)."""
    mask = np.zeros(shape, dtype=bool)
    ui, vi = np.round(u[visible]).astype(int), np.round(v[visible]).astype(int)
    ui, vi = np.clip(ui, 0, shape[1] - 1), np.clip(vi, 0, shape[0] - 1)
    mask[vi, ui] = True
    for _ in range(grow):
        grown = mask.copy()
        grown[1:] |= mask[:-1]
        grown[:-1] |= mask[1:]
        grown[:, 1:] |= mask[:, :-1]
        grown[:, :-1] |= mask[:, 1:]
        mask = grown
    return mask

"""Tests of example_pcl.demo's own part: the picture."""
import numpy as np

from example_pcl import demo


def test_write_picture(tmp_path):
    """write_picture writes a PNG of the scene with the plane and model overlaid."""
    z = np.linspace(0.8, 2.0, 48 * 64).reshape(48, 64)
    v, u = np.mgrid[0:48, 0:64]
    xyz = np.stack([(u - 31.5) * z / 525, (v - 23.5) * z / 525, z], axis=-1).astype(np.float32)
    path = demo.write_picture(tmp_path / "sub" / "out.png", xyz, xyz[30:, :].reshape(-1, 3),
                              xyz[10:12, 10:12].reshape(-1, 3), "title")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

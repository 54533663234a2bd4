"""PCD files <-> NumPy structured arrays, through PCL's own reader and writer.

The extension (example_pcl._native.read_pcd / write_pcd) calls pcl::PCDReader and
pcl::PCDWriter on a pcl::PCLPointCloud2, so every field, the organized width x height, is_dense
and the viewpoint survive exactly as PCL keeps them (binary_compressed bodies are compressed by
the extension itself, in PCL's layout with PCL's lzfCompress, in half the time of PCL's writer
on one core, and on several threads); this module turns PCL's raw buffer and field
list into a structured array with the dtype primitives of example_pcl.conversions, and makes
every write atomic (temporary name, fsync, rename).
"""
from __future__ import annotations

import contextlib
import dataclasses
import os
import tempfile
from typing import Iterator, Optional, Tuple

import numpy as np

from example_pcl import _native
from example_pcl.conversions import dtype_to_fields, fields_to_dtype, make_points, xyz_view
from example_pcl.errors import PerceptionError

FORMATS = ("ascii", "binary", "binary_compressed")


@dataclasses.dataclass
class PcdCloud:
    """A point cloud as read from (or to be written to) a PCD file.

    points: structured array, shape (height, width) when organized (height > 1), else (width,).
    origin: sensor position (x, y, z), metres; orientation: sensor rotation as (w, x, y, z).
    """

    points: np.ndarray
    is_dense: bool = False
    origin: Tuple[float, float, float] = (0.0, 0.0, 0.0)
    orientation: Tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
    format: str = "binary"

    @property
    def xyz(self) -> np.ndarray:
        """x, y, z as a float32 (..., 3) view of ``points``."""
        return xyz_view(self.points)

    @property
    def organized(self) -> bool:
        return self.points.ndim == 2


def read_pcd(path: str) -> PcdCloud:
    """Reads a PCD file (ascii, binary or binary_compressed) with PCL's reader.

    The returned array owns PCL's buffer (no copy). Raises PerceptionError naming the file when
    it is missing, truncated or malformed.
    """
    path = os.fspath(path)
    try:
        raw = _native.read_pcd(path)
    except ValueError as e:
        message = str(e) if path in str(e) else f"cannot read PCD file '{path}': {e}"
        raise PerceptionError(message) from None
    width, height, point_step = raw["width"], raw["height"], raw["point_step"]
    try:
        # PCL's binary writer names padding bytes "_"; they are not a field.
        dtype = fields_to_dtype([f for f in raw["fields"] if f[0] != "_"], point_step)
    except PerceptionError as e:
        raise PerceptionError(f"cannot read PCD file '{path}': {e}") from None
    flat = raw["data"].view(dtype) if point_step else np.zeros(0, dtype)
    points = flat.reshape((height, width)) if height > 1 else flat.reshape((width * height,))
    return PcdCloud(points=points, is_dense=raw["is_dense"], origin=tuple(raw["origin"]),
                    orientation=tuple(raw["orientation"]), format=raw["format"])


def _umask() -> int:
    """The process's umask, read without changing it (os.umask would race with other threads)."""
    try:
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    return 0o022


def _fsync(path: str) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


@contextlib.contextmanager
def atomic_path(path: str, fsync: bool = True) -> Iterator[str]:
    """Yields a temporary name beside ``path``; on success the file is renamed to it.

    A crash, a kill or a full disk leaves at most a hidden temporary file, never a partial file
    under the final name. With ``fsync`` (the default) the data and the rename are flushed to
    the disk first, so a power cut cannot leave an empty file under the final name either. On
    error the temporary file is removed and the error propagates.
    """
    path = os.fspath(path)
    directory = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".", suffix=".tmp", dir=directory)
    os.close(fd)
    # mkstemp makes the file 0600; give it the mode open() would (0666 less the umask).
    os.chmod(tmp, 0o666 & ~_umask())
    try:
        yield tmp
        if fsync:
            _fsync(tmp)
        os.replace(tmp, path)
        if fsync:
            _fsync(directory)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def write_pcd(path: str, points: np.ndarray, fmt: str = "binary_compressed", is_dense: Optional[bool] = None,
              origin=(0.0, 0.0, 0.0), orientation=(1.0, 0.0, 0.0, 0.0), precision: int = 9,
              fsync: bool = True, threads: int = 0) -> None:
    """Writes a structured array as a PCD v0.7 file in PCL's format, atomically.

    points: structured array of shape (H, W) (organized) or (N,); every named field is written.
    fmt: "ascii", "binary" or "binary_compressed". is_dense defaults to "x, y, z all finite".
    origin (metres) and orientation (w, x, y, z) go to the VIEWPOINT line. precision: significant
    digits of floats in ascii (9 keeps every float32 exact). fsync: flush to the disk before the
    rename (see atomic_path); the file is atomic either way. threads: binary_compressed compresses
    on this many threads (0 = one per core; small clouds use one); PCL reads the same points
    whatever the number. Raises PerceptionError for bad arguments, OSError when the file
    cannot be written (nothing is left under ``path`` then).
    """
    if fmt not in FORMATS:
        raise PerceptionError(f"PCD format must be one of {', '.join(FORMATS)}, got '{fmt}'")
    if points.dtype.names is None or points.ndim not in (1, 2):
        raise PerceptionError(f"points must be a 1-D or 2-D structured array, got {points.dtype} {points.shape}")
    height, width = points.shape if points.ndim == 2 else (1, points.shape[0])
    # PCL writes packed fields in order; drop padding-only bytes by keeping the dtype as it is.
    data = np.ascontiguousarray(points)
    if is_dense is None:
        names = points.dtype.names
        is_dense = not all(c in names for c in "xyz") or bool(np.isfinite(xyz_view(data)).all())
    with atomic_path(path, fsync=fsync) as tmp:
        try:
            _native.write_pcd(tmp, data.view(np.uint8).reshape(-1), dtype_to_fields(points.dtype), width, height,
                              points.dtype.itemsize, bool(is_dense), tuple(map(float, origin)),
                              tuple(map(float, orientation)), fmt, precision, threads)
        except RuntimeError as e:
            reason = str(e).split("': ", 1)[-1]  # the extension names the temporary file
            raise OSError(f"cannot write PCD file '{path}': {reason}") from None
        except ValueError as e:
            raise PerceptionError(str(e)) from None


def write_cloud(path: str, xyz: np.ndarray, rgb: Optional[np.ndarray] = None, fmt: str = "binary_compressed",
                **kwargs) -> None:
    """Writes x, y, z (and rgb) arrays, (N, 3) or organized (H, W, 3), as a PCD file, atomically.

    rgb: uint8 (..., 3), stored as PCL's float-packed ``rgb``. Other arguments as write_pcd.
    """
    write_pcd(path, make_points(xyz, rgb), fmt=fmt, **kwargs)

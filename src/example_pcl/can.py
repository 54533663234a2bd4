"""The result type of every can finder: :class:`Can`, a can on the table (or on an object), sensor frame.

Both the operator's modes 2-3 (example_pcl.can_finder) and the automatic search
(example_pcl.auto_finder, mode 4) return it. Pure NumPy; knows nothing of ROS.
"""
from dataclasses import dataclass, field
from typing import Optional, Tuple

import numpy as np

from example_pcl import geometry


@dataclass(frozen=True, eq=False)
class Can:
    """A can found in a cloud. Lengths in metres, angles in radians, sensor frame unless named.

    T_sensor_from_can: 4x4 float64, origin at the centre of the can's base on the table, z up its
    axis (the table normal), x as the plane frame's; radius, height: of the can (fitted by mode 4,
    the configured or mode 4's size for modes 2-3); rms_error: RMS radial residual of the side
    points within r_eps of the circle; arc_coverage: angular span of those points around the
    axis (0..2 pi; about pi for the visible half); n_points: points the fit looked at (mode 4: its
    cluster; modes 2-3: the points above the table near the can); n_fit_points: of them, those
    within r_eps of the circle; center_plane: float64 (2,), the axis (cx, cy) in the plane frame
    (lying: the axis's middle seen from above);
    iterations: of the fit (0 for mode 2's guess and for mode 4, whose fit is not continued);
    converged: of the fit (True for mode 2's guess, which is not iterated); shape_error (mode 4
    only, else None): the systematic radial deviation (see auto_finder.shape_error); indices
    (mode 4 only, else None): int64 indices of its cluster's points into the flattened cloud;
    support: what the can stands on ("table"; "object" or "can": stacked on another object or a
    found can); base_seen: False when the base was hidden behind an object in front and inferred
    on the support; support_height: the base's height above the table (m; 0 on the table); lying:
    the can lies on its side (its axis, z of T_sensor_from_can, parallel to the table; origin the
    centre of one end, height its length); end_seen: False when the image's edge cuts its far end
    (the top, or a lying can's other end; height is then the length seen; a lying can's origin is
    the end seen, and base_seen False when the edge cuts both), or an object in front hides a lying
    can's other end. Unorganized clouds: True unless hidden. ends_hidden: which of a lying can's ends
    (its origin's, the other) an object standing apart in front hides (mode 4's search; a tracker's
    refit keeps its detection's).
    """

    T_sensor_from_can: np.ndarray
    radius: float
    height: float
    rms_error: float
    arc_coverage: float
    n_points: int
    n_fit_points: int
    center_plane: np.ndarray
    iterations: int = 0
    converged: bool = True
    shape_error: Optional[float] = None
    indices: Optional[np.ndarray] = field(default=None, repr=False)
    support: str = "table"
    base_seen: bool = True
    support_height: float = 0.0
    lying: bool = False
    end_seen: bool = True
    ends_hidden: Tuple[bool, bool] = (False, False)

    @property
    def base_center(self):
        """Centre of the can's base, sensor frame (m): float64 (3,)."""
        return self.T_sensor_from_can[:3, 3].copy()

    @property
    def axis(self):
        """Unit axis of the can (up from the table when upright), sensor frame: float64 (3,)."""
        return self.T_sensor_from_can[:3, 2].copy()

    @property
    def footprint_center(self):
        """The middle of its footprint, sensor frame (m): the base centre, or a lying can's axis' middle."""
        return geometry.footprint_center(self.base_center, self.axis, self.height, self.lying)

    def to_dict(self):
        """JSON-able dict of everything but the indices (base_center and axis included)."""
        return {"base_center": self.base_center.tolist(), "axis": self.axis.tolist(), "radius": self.radius,
                "height": self.height, "rms_error": self.rms_error, "shape_error": self.shape_error,
                "arc_coverage": self.arc_coverage, "n_points": self.n_points, "n_fit_points": self.n_fit_points,
                "center_plane": np.asarray(self.center_plane).tolist(), "iterations": self.iterations,
                "converged": self.converged, "support": self.support, "base_seen": self.base_seen,
                "support_height": self.support_height, "lying": self.lying, "end_seen": self.end_seen,
                "ends_hidden": list(self.ends_hidden),
                "T_sensor_from_can": self.T_sensor_from_can.tolist()}

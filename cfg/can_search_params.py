"""The automatic can search's tunables, shared by FindCan.cfg and CanTracker.cfg.

Each entry: (name, type, default, min, max, description). Names are AutoConfig's field names
(example_pcl.auto_finder) except where find_can's operator steps already use the name: those get
an ``auto_`` prefix; the groups lying and sensor hold fields of its CylinderSearchConfig
(AutoConfig.cylinders): those named lying_*, and projector_offset. Lengths in metres, angles in
radians; test_reconfigure checks the defaults against AutoConfig's.
"""

GROUPS = {
    "table": [
        ("ransac_step", "int", 8, 1, 32, "RANSAC sees every n-th pixel in each direction (px)"),
        ("plane_distance", "double", 0.015, 0.001, 0.1, "RANSAC inlier distance (m)"),
        ("max_planes", "int", 3, 1, 10, "planes searched at most"),
        ("min_plane_fraction", "double", 0.05, 0.0, 1.0, "a plane needs this fraction of the subsampled points"),
        ("max_tilt", "double", 0.35, 0.0, 1.57, "with an up prior: the table normal within this of up (rad)"),
        ("refine_step", "int", 3, 1, 32, "the plane refinement uses every n-th pixel (px)"),
        ("refine_band", "double", 0.01, 0.001, 0.1, "the refinement fits the points within this of the plane (m)"),
        ("auto_refine_iterations", "int", 3, 1, 20, "refinement passes at most"),
        ("support_step", "int", 4, 1, 32, "support is counted on every n-th pixel (px)"),
        ("min_support", "int", 10, 0, 100000, "points standing on a plane that make it the table"),
    ],
    "objects": [
        ("min_height", "double", 0.015, 0.0, 0.2, "objects start this high above the table (m)"),
        ("max_height", "double", 0.4, 0.05, 2.0, "and end this high above it (m)"),
        ("cluster_distance", "double", 0.02, 0.001, 0.2, "neighbouring points closer than this join a cluster (m)"),
        ("min_cluster_points", "int", 50, 1, 100000, "smaller clusters are noise"),
    ],
    "fit": [
        ("fit_bottom", "double", 0.01, 0.0, 0.2, "side points start this high above the table (m)"),
        ("top_margin", "double", 0.01, 0.0, 0.2, "and end this far below the object's top (m)"),
        ("max_fit_points", "int", 600, 10, 100000, "larger sides are subsampled for the fit"),
        ("fit_tolerance", "double", 1e-5, 1e-8, 1e-2, "the circle fit stops at a shorter step (m)"),
        ("fit_iterations", "int", 20, 1, 500, "the circle fit stops after this many iterations"),
        ("noise_coefficient", "double", 1.425e-3, 0.0, 0.02, "depth noise sigma = this x range^2 (1/m)"),
        ("auto_r_eps", "double", 0.006, 0.0005, 0.05, "a side point is an inlier within this of the circle (m)"),
        ("r_eps_sigmas", "double", 3.0, 0.0, 20.0, "or within this many depth-noise sigmas, if wider"),
    ],
    "criterion": [
        ("max_base_gap", "double", 0.03, 0.0, 0.5, "a can's lowest point is at most this above the table (m)"),
        ("min_can_height", "double", 0.04, 0.0, 1.0, "a can is at least this tall (m)"),
        ("min_fit_points", "int", 30, 3, 100000, "side points a can needs"),
        ("min_radius", "double", 0.015, 0.001, 0.5, "smallest can radius (m)"),
        ("max_radius", "double", 0.08, 0.002, 0.5, "largest can radius (m)"),
        ("min_inlier_fraction", "double", 0.8, 0.0, 1.0, "of the side points within the inlier distance"),
        ("max_rms", "double", 0.003, 0.0001, 0.05, "rms radial residual at most (m)"),
        ("max_rms_sigmas", "double", 1.0, 0.0, 20.0, "or this many depth-noise sigmas, if larger"),
        ("shape_bins", "int", 8, 1, 64, "arcs the side is split into for the shape error"),
        ("max_shape_error", "double", 0.001, 0.0, 0.05, "rms of the arcs' mean residuals at most (m)"),
        ("min_arc", "double", 1.8, 0.0, 6.2832, "the side is seen around at least this (rad)"),
    ],
    # The cylinder search's lying step (can_search.CylinderSearchConfig, example_pcl.lying).
    "lying": [
        ("lying_gap", "double", 0.01, 0.0, 0.1, "a lying can's axis is one radius above the table to within this (m)"),
        ("lying_directions", "int", 36, 4, 360, "axis directions scanned over 180 degrees"),
        ("lying_join_angle", "double", 0.1, 0.0, 1.57, "two lying parts are one can within this angle (rad)"),
        ("lying_join_offset", "double", 0.015, 0.0, 0.1, "and each axis this near the other's middle (m)"),
        ("lying_join_gap", "double", 0.15, 0.0, 1.0, "and at most this far apart along it (m)"),
    ],
    # The depth sensor (can_search.CylinderSearchConfig): no depth where its IR projector casts no light.
    "sensor": [
        ("projector_offset", "double", 0.075, -0.2, 0.2,
         "the IR projector's offset from the depth camera along its +x (m; a Kinect's 0.075, 0: not known)"),
    ],
}

# AutoConfig field of each prefixed name.
FIELD_OF = {"auto_refine_iterations": "refine_iterations", "auto_r_eps": "r_eps"}

CLUSTERING = ("auto", "organized", "euclidean")

# AutoConfig.search (example_pcl.auto_finder.SEARCHES).
SEARCHES = ("cylinders", "clusters")


def add_can_search(gen, level=0):
    """Adds the groups table, objects, fit, criterion, lying and sensor (and the clustering and search
    enums) to a generator."""
    from dynamic_reconfigure.parameter_generator_catkin import int_t, double_t, str_t

    types = {"int": int_t, "double": double_t}
    groups = {}
    for group, params in GROUPS.items():
        groups[group] = gen.add_group(group)
        for name, kind, default, low, high, description in params:
            groups[group].add(name, types[kind], level, description, default, low, high)
    clustering = gen.enum([gen.const(c, str_t, c, f"{c} clustering") for c in CLUSTERING],
                          "organized grid (an H x W cloud), the Euclidean clusters of PCL, or auto")
    groups["objects"].add("clustering", str_t, level, "how points above the table are clustered", "auto",
                          edit_method=clustering)
    search = gen.enum([gen.const(f"search_{c}", str_t, c, f"{c} search") for c in SEARCHES],
                      "cans inside clusters (cylinders, issue 13) or each cluster one can (clusters, issue 5)")
    groups["objects"].add("search", str_t, level, "how cans are looked for in the objects", "cylinders",
                          edit_method=search)
    return groups

"""example_pcl._native against NumPy references: transforms, filters, centroids, normals, RANSAC."""
import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from example_pcl import _native


def rigid(rx=0.3, ry=-0.2, rz=1.1, t=(0.5, -1.0, 2.0)):
    def rot(axis, a):
        c, s = np.cos(a), np.sin(a)
        i, j = [k for k in range(3) if k != axis]
        m = np.eye(3)
        m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
        return m

    T = np.eye(4)
    T[:3, :3] = rot(0, rx) @ rot(1, ry) @ rot(2, rz)
    T[:3, 3] = t
    return T


def reference_transform(points, T):
    return (points.astype(np.float64) @ T[:3, :3].T + T[:3, 3]).astype(np.float32)


@pytest.fixture
def cloud():
    rng = np.random.default_rng(1)
    pts = rng.uniform(-2, 2, (1000, 3)).astype(np.float32)
    pts[::7] = np.nan
    return pts


def padded_buffer(points, point_step=32, offset=0):
    """A PointCloud2-like buffer: x, y, z at `offset` inside point_step bytes, and a float32 strided view of it."""
    buf = np.zeros(len(points) * point_step, np.uint8)
    view = np.lib.stride_tricks.as_strided(buf[offset:].view(np.float32), shape=(len(points), 3),
                                           strides=(point_step, 4))
    view[...] = points
    return buf, view


def test_transform_matches_numpy(cloud):
    """transform_cloud on (N, 3) equals R p + t, NaN points stay NaN."""
    T = rigid()
    out = _native.transform_cloud(cloud, T)
    assert out.dtype == np.float32 and out.shape == cloud.shape
    assert_allclose(out, reference_transform(cloud, T), rtol=1e-6, atol=1e-5)
    assert np.isnan(out[::7]).all()


def test_transform_organized_keeps_shape(cloud):
    """An (H, W, 3) cloud transforms to (H, W, 3), row-major order kept."""
    organized = cloud[:990].reshape(30, 33, 3)
    out = _native.transform_cloud(organized, rigid())
    assert out.shape == (30, 33, 3)
    assert_allclose(out.reshape(-1, 3), reference_transform(cloud[:990], rigid()), rtol=1e-6, atol=1e-5)


def test_transform_strided_view_without_copy(cloud):
    """A strided float32 view inside a padded point buffer is read in place, and in place written back."""
    buf, view = padded_buffer(cloud, point_step=32, offset=4)
    assert not view.flags.c_contiguous
    T = rigid()
    assert_allclose(_native.transform_cloud(view, T), reference_transform(cloud, T), rtol=1e-6, atol=1e-5)
    before = buf.copy()
    result = _native.transform_cloud(view, T, out=view)
    assert result is view or np.shares_memory(result, buf)
    assert_allclose(view, reference_transform(cloud, T), rtol=1e-6, atol=1e-5)
    # bytes outside x, y, z untouched
    mask = np.ones(32, bool)
    mask[4:16] = False
    assert_array_equal(buf.reshape(-1, 32)[:, mask], before.reshape(-1, 32)[:, mask])


def test_transform_non_contiguous_rows():
    """A column-sliced organized view (row stride != width * point stride) transforms correctly."""
    base = np.random.default_rng(2).normal(size=(20, 40, 3)).astype(np.float32)
    view = base[:, ::3]
    out = _native.transform_cloud(view, rigid())
    assert_allclose(out, reference_transform(view.reshape(-1, 3), rigid()).reshape(view.shape), rtol=1e-6, atol=1e-5)


def test_transform_read_only_in_place_rejected(cloud):
    """Transforming a read-only array in place raises ValueError, nothing crashes."""
    cloud.flags.writeable = False
    with pytest.raises(ValueError, match="read-only"):
        _native.transform_cloud(cloud, rigid(), out=cloud)


@pytest.mark.parametrize("bad, error, text", [
    (np.zeros((4, 3), np.float64), TypeError, "float64 array of shape \\(4, 3\\)"),
    (np.zeros((4, 2), np.float32), ValueError, "shape \\(4, 2\\)"),
    (np.zeros(3, np.float32), ValueError, "shape \\(3,\\)"),
    (np.zeros((2, 2, 2, 3), np.float32), ValueError, "shape \\(2, 2, 2, 3\\)"),
])
def test_bad_points_named_in_error(bad, error, text):
    """A wrong dtype raises TypeError and a wrong shape ValueError, naming what was received."""
    with pytest.raises(error, match=text):
        _native.transform_cloud(bad, np.eye(4))
    with pytest.raises(error, match=text):
        _native.filter_z_band(bad, 0.0, 1.0)


@pytest.mark.parametrize("T", [np.eye(3), np.full((4, 4), np.nan), np.ones((4, 4))])
def test_bad_transform_rejected(T):
    """A transform that is not a finite 4x4 homogeneous matrix raises ValueError."""
    with pytest.raises(ValueError):
        _native.transform_cloud(np.zeros((2, 3), np.float32), T)


def test_empty_and_one_point():
    """Empty input gives empty output; one point transforms like any other."""
    assert _native.transform_cloud(np.zeros((0, 3), np.float32), rigid()).shape == (0, 3)
    assert _native.filter_above_z(np.zeros((0, 3), np.float32), 0.0).size == 0
    p = np.array([[1.0, 2.0, 3.0]], np.float32)
    assert_allclose(_native.transform_cloud(p, rigid()), reference_transform(p, rigid()), rtol=1e-6)


def test_large_coordinates():
    """Coordinates near 1e6 m transform with float32 relative accuracy."""
    p = np.array([[1e6, -1e6, 5e5]], np.float32)
    assert_allclose(_native.transform_cloud(p, rigid()), reference_transform(p, rigid()), rtol=1e-6)


def test_z_filters_match_numpy(cloud):
    """filter_z_band and filter_above_z return the indices NumPy's comparisons give; NaN never kept."""
    z = cloud[:, 2]
    with np.errstate(invalid="ignore"):
        assert_array_equal(_native.filter_z_band(cloud, 0.5, 0.25), np.flatnonzero(np.abs(z - 0.5) <= 0.25))
        assert_array_equal(_native.filter_above_z(cloud, 0.1), np.flatnonzero(z > 0.1))
    assert _native.filter_z_band(cloud, 0.0, 1.0).dtype == np.int64
    with pytest.raises(ValueError):
        _native.filter_z_band(cloud, 0.0, -1.0)


def test_z_filter_on_strided_organized_view(cloud):
    """Indices from an organized strided view count points row-major."""
    _, view = padded_buffer(cloud[:990], point_step=20)
    organized = np.lib.stride_tricks.as_strided(view, shape=(30, 33, 3), strides=(33 * 20, 20, 4))
    with np.errstate(invalid="ignore"):
        assert_array_equal(_native.filter_above_z(organized, 0.0), np.flatnonzero(cloud[:990, 2] > 0))


def test_extract_and_bounds(cloud):
    """extract gathers the indexed points; an out-of-range index raises ValueError."""
    idx = np.array([3, 0, 999, 7])
    assert_array_equal(_native.extract(cloud, idx), cloud[idx])
    with pytest.raises(ValueError, match="out of range"):
        _native.extract(cloud, np.array([1000]))
    with pytest.raises(ValueError, match="out of range"):
        _native.extract(cloud, np.array([-1]))
    with pytest.raises(TypeError):
        _native.extract(cloud, np.array([0.5]))


def test_centroid_skips_nan_and_inf(cloud):
    """centroid averages only finite points, optionally only the indexed ones."""
    cloud[1] = [np.inf, 0, 0]
    finite = np.isfinite(cloud).all(axis=1)
    assert_allclose(_native.centroid(cloud), cloud[finite].astype(np.float64).mean(axis=0), rtol=1e-9)
    idx = np.array([0, 1, 2, 7, 8])
    sub = cloud[idx][np.isfinite(cloud[idx]).all(axis=1)]
    assert_allclose(_native.centroid(cloud, idx), sub.astype(np.float64).mean(axis=0), rtol=1e-9)
    with pytest.raises(ValueError, match="no finite"):
        _native.centroid(np.full((5, 3), np.nan, np.float32))


def test_squared_distances(cloud):
    """squared_distances equals |p - c|^2, NaN for NaN points."""
    c = np.array([0.1, -0.2, 0.3])
    assert_allclose(_native.squared_distances(cloud, c), ((cloud - c) ** 2).sum(axis=1), rtol=1e-5, equal_nan=True)


def test_normal_of_plane_matches_eigh():
    """compute_point_normal gives the least-squares plane NumPy's covariance + eigh gives, curvature ~0."""
    rng = np.random.default_rng(3)
    n = np.array([0.2, -0.3, 0.9])
    n /= np.linalg.norm(n)
    u = np.cross(n, [1, 0, 0])
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    a, b = rng.uniform(-0.1, 0.1, (2, 500))
    pts = (np.outer(a, u) + np.outer(b, v) + [0.3, 0.1, 1.2] + np.outer(rng.normal(0, 1e-3, 500), n)).astype(np.float32)
    pts[::10] = np.nan
    plane, curvature = _native.compute_point_normal(pts)
    good = pts[np.isfinite(pts).all(axis=1)].astype(np.float64)
    w, V = np.linalg.eigh(np.cov(good.T))
    ref = V[:, 0]
    assert abs(abs(plane[:3] @ ref) - 1) < 1e-5
    assert_allclose(plane[:3] @ good.mean(axis=0) + plane[3], 0, atol=1e-5)
    assert_allclose(curvature, w[0] / w.sum(), rtol=1e-3, atol=1e-7)


@pytest.mark.parametrize("n", [0, 1, 2])
def test_normal_needs_three_points(n):
    """Fewer than three finite points raise ValueError saying so."""
    pts = np.ones((n, 3), np.float32)
    with pytest.raises(ValueError, match="at least 3"):
        _native.compute_point_normal(pts)
    with pytest.raises(ValueError, match="at least 3"):
        _native.compute_point_normal(np.full((10, 3), np.nan, np.float32))


def test_normal_with_indices():
    """compute_point_normal with indices uses only those points."""
    pts = np.zeros((6, 3), np.float32)
    pts[:3] = [[0, 0, 1], [1, 0, 1], [0, 1, 1]]  # plane z = 1
    pts[3:] = [[5, 5, 9], [7, 1, -3], [2, 8, 4]]
    plane, _ = _native.compute_point_normal(pts, np.array([0, 1, 2]))
    assert_allclose(abs(plane[2]), 1, atol=1e-6)
    assert_allclose(plane[3] / plane[2], -1, atol=1e-6)


def test_segment_plane_finds_dominant_plane():
    """segment_plane finds a noisy plane among outliers, inliers index the input, NaN skipped."""
    rng = np.random.default_rng(4)
    plane_pts = np.c_[rng.uniform(-1, 1, (2000, 2)), rng.normal(0.8, 0.002, 2000)]
    outliers = rng.uniform(-1, 1, (500, 3))
    pts = np.r_[plane_pts, outliers, np.full((10, 3), np.nan)].astype(np.float32)
    plane, inliers = _native.segment_plane(pts, 0.01, 200)
    assert_allclose(abs(plane[2]), 1, atol=1e-3)
    assert_allclose(-plane[3] / plane[2], 0.8, atol=2e-3)
    assert (inliers < 2000).mean() > 0.95 and len(inliers) > 1900
    plane2, _ = _native.segment_plane(pts, 0.01, 200, axis=(0, 0, 1), eps_angle=0.1)
    assert_allclose(abs(plane2[2]), 1, atol=1e-3)


# --- clustering -----------------------------------------------------------------------------------


def blobs_grid():
    """A 40x60 organized grid (m): a flat floor at z = 0 with two raised blocks (z = 0.1) and a
    NaN hole; the blocks are 5 columns apart (0.05 m), far more than the 0.01 m pixel pitch."""
    v, u = np.mgrid[0:40, 0:60].astype(np.float32)
    xyz = np.stack([u * 0.01, v * 0.01, np.zeros_like(u)], axis=-1)
    xyz[5:15, 5:20, 2] = 0.1
    xyz[5:25, 25:35, 2] = 0.1
    xyz[30, 30] = np.nan
    return xyz


def test_organized_clusters_split_at_gaps_largest_first():
    """Connected components of the raised points: two clusters, largest first, flattened indices."""
    xyz = blobs_grid()
    clusters = _native.organized_clusters(xyz, 0.015, z_min=0.05)
    assert [len(c) for c in clusters] == [200, 150]
    rows, cols = np.divmod(clusters[1], 60)
    assert rows.min() == 5 and rows.max() == 14 and cols.min() == 5 and cols.max() == 19
    assert all((np.diff(c) > 0).all() for c in clusters)


def test_organized_clusters_distance_and_size_limits():
    """A 3-D jump larger than max_distance separates neighbours; min/max_points drop clusters."""
    xyz = blobs_grid()
    xyz[5:15, 12:20, 2] = 0.2  # a 0.1 m step inside the first block
    assert sorted(len(c) for c in _native.organized_clusters(xyz, 0.015, z_min=0.05)) == [70, 80, 200]
    assert sorted(len(c) for c in _native.organized_clusters(xyz, 0.2, z_min=0.05)) == [150, 200]
    assert [len(c) for c in _native.organized_clusters(xyz, 0.015, min_points=75, max_points=100,
                                                       z_min=0.05)] == [80]


def test_organized_matches_euclidean_clusters():
    """On an organized grid, connected components and PCL's Euclidean clusters agree."""
    xyz = blobs_grid()
    idx = np.flatnonzero(xyz[..., 2].ravel() > 0.05)
    organized = _native.organized_clusters(xyz, 0.015, z_min=0.05)
    euclidean = _native.euclidean_clusters(xyz, 0.015, indices=idx)
    assert len(organized) == len(euclidean) == 2
    for a, b in zip(organized, euclidean):
        assert_array_equal(a, b)


def test_euclidean_clusters_skip_nan_and_limit_sizes():
    """euclidean_clusters ignores NaN points and drops clusters outside [min_points, max_points]."""
    pts = np.r_[np.zeros((5, 3)), np.full((3, 3), np.nan), np.ones((20, 3))].astype(np.float32)
    clusters = _native.euclidean_clusters(pts, 0.01)
    assert [len(c) for c in clusters] == [20, 5]
    assert_array_equal(clusters[1], np.arange(5))
    assert [len(c) for c in _native.euclidean_clusters(pts, 0.01, min_points=6)] == [20]


@pytest.mark.parametrize("call, error", [
    (lambda: _native.organized_clusters(np.zeros((10, 3), np.float32), 0.01), ValueError),
    (lambda: _native.organized_clusters(np.zeros((4, 4, 3)), 0.01), TypeError),
    (lambda: _native.organized_clusters(np.zeros((4, 4, 3), np.float32), 0.0), ValueError),
    (lambda: _native.organized_clusters(np.zeros((4, 4, 3), np.float32), 0.01, min_points=0), ValueError),
    (lambda: _native.euclidean_clusters(np.zeros((4, 3), np.float32), -1.0), ValueError),
    (lambda: _native.euclidean_clusters(np.zeros((4, 3), np.float32), 0.1, indices=np.array([7])), ValueError),
])
def test_cluster_arguments_checked(call, error):
    """Bad shapes, dtypes, distances, sizes and indices raise at the boundary."""
    with pytest.raises(error):
        call()


def test_version_is_package_xml():
    """_native.__version__ is package.xml's <version>, passed in by CMake."""
    import pathlib
    import xml.etree.ElementTree as ET
    package_xml = pathlib.Path(__file__).resolve().parents[2] / "package.xml"
    assert _native.__version__ == ET.parse(package_xml).getroot().findtext("version").strip()


def test_every_binding_documented_with_keyword_names():
    """Every function of _native has a docstring and names all its arguments (no pybind11 arg0, arg1...)."""
    functions = [name for name in dir(_native) if callable(getattr(_native, name)) and not name.startswith("_")]
    assert functions
    for name in functions:
        doc = getattr(_native, name).__doc__
        signature, _, text = doc.partition("\n")
        assert signature.startswith(f"{name}(") and text.strip(), name
        assert "arg0" not in signature, signature


def test_write_pcd_rejects_a_strided_buffer(tmp_path):
    """write_pcd reads data as contiguous bytes, so a buffer with gaps is refused, not written wrong."""
    points = np.zeros((10, 6), np.float32)[:, :3]
    with pytest.raises(ValueError, match="C-contiguous"):
        _native.write_pcd(str(tmp_path / "s.pcd"), points, [("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1)],
                          10, 1, 12, True, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0))

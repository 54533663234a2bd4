// Segmentation: model fitting by RANSAC through PCL's SACSegmentation, and clustering (PCL's
// Euclidean cluster extraction, and connected components on the organized grid). Each copies the
// finite points it needs with the GIL held and releases the GIL only around the work on that
// copy (common.hpp's GIL policy).
#include <pcl/ModelCoefficients.h>
#include <pcl/search/kdtree.h>
#include <pcl/segmentation/extract_clusters.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/sample_consensus/method_types.h>
#include <pcl/sample_consensus/model_types.h>
#include <pcl/segmentation/sac_segmentation.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>
#include <vector>

#include "common.hpp"
#include "finite_cloud.hpp"

namespace example_pcl {
namespace {

py::tuple segment_plane(const py::array& points, double distance_threshold, int max_iterations,
                        std::optional<std::array<float, 3>> axis, double eps_angle, double probability) {
  const PointView v = point_view(points);
  if (!(distance_threshold > 0)) throw std::invalid_argument("distance_threshold must be > 0 (metres)");
  if (max_iterations < 1) throw std::invalid_argument("max_iterations must be >= 1");
  const FiniteCloud finite = finite_cloud(v);
  if (finite.cloud->size() < 3) throw std::invalid_argument("plane segmentation needs at least 3 finite points");
  pcl::ModelCoefficients coefficients;
  pcl::PointIndices inliers;
  {
    py::gil_scoped_release nogil;
    pcl::SACSegmentation<pcl::PointXYZ> seg;
    seg.setOptimizeCoefficients(true);
    seg.setMethodType(pcl::SAC_RANSAC);
    seg.setDistanceThreshold(distance_threshold);
    seg.setMaxIterations(max_iterations);
    seg.setProbability(probability);
    if (axis) {
      seg.setModelType(pcl::SACMODEL_PERPENDICULAR_PLANE);
      seg.setAxis(Eigen::Vector3f((*axis)[0], (*axis)[1], (*axis)[2]));
      seg.setEpsAngle(eps_angle);
    } else {
      seg.setModelType(pcl::SACMODEL_PLANE);
    }
    seg.setInputCloud(finite.cloud);
    seg.segment(inliers, coefficients);
  }
  if (inliers.indices.empty() || coefficients.values.size() != 4)
    throw std::invalid_argument("no plane found");
  py::array_t<float> plane(4);
  std::copy(coefficients.values.begin(), coefficients.values.end(), plane.mutable_data());
  py::array_t<std::int64_t> idx(static_cast<py::ssize_t>(inliers.indices.size()));
  auto* p = idx.mutable_data();
  for (size_t i = 0; i < inliers.indices.size(); ++i) p[i] = finite.original[static_cast<size_t>(inliers.indices[i])];
  return py::make_tuple(plane, idx);
}


// Clusters as a Python list of int64 index arrays, largest first (ties: lowest first index).
py::list cluster_list(std::vector<std::vector<std::int64_t>>& clusters) {
  std::stable_sort(clusters.begin(), clusters.end(),
                   [](const auto& a, const auto& b) { return a.size() > b.size(); });
  py::list out;
  for (const auto& c : clusters) {
    py::array_t<std::int64_t> a(static_cast<py::ssize_t>(c.size()));
    std::copy(c.begin(), c.end(), a.mutable_data());
    out.append(a);
  }
  return out;
}

void check_cluster_sizes(py::ssize_t min_points, py::ssize_t max_points) {
  if (min_points < 1) throw std::invalid_argument("min_points must be >= 1");
  if (max_points < min_points) throw std::invalid_argument("max_points must be >= min_points");
}

py::list euclidean_clusters(const py::array& points, double tolerance, py::ssize_t min_points,
                            py::ssize_t max_points, std::optional<py::array> indices) {
  const PointView v = point_view(points);
  if (!(tolerance > 0)) throw std::invalid_argument("tolerance must be > 0 (metres)");
  check_cluster_sizes(min_points, max_points);
  std::optional<py::array_t<std::int64_t>> idx;
  if (indices) idx = checked_indices(*indices, v.size());
  const FiniteCloud finite = finite_cloud(v, idx);
  const auto& cloud = finite.cloud;
  std::vector<std::vector<std::int64_t>> clusters;
  {
    py::gil_scoped_release nogil;
    if (!cloud->empty()) {
      auto tree = std::make_shared<pcl::search::KdTree<pcl::PointXYZ>>();
      tree->setInputCloud(cloud);
      std::vector<pcl::PointIndices> found;
      pcl::EuclideanClusterExtraction<pcl::PointXYZ> ec;
      ec.setClusterTolerance(tolerance);
      ec.setMinClusterSize(static_cast<pcl::uindex_t>(std::min<py::ssize_t>(min_points, std::numeric_limits<int>::max())));
      ec.setMaxClusterSize(static_cast<pcl::uindex_t>(std::min<py::ssize_t>(max_points, std::numeric_limits<int>::max())));
      ec.setSearchMethod(tree);
      ec.setInputCloud(cloud);
      ec.extract(found);
      for (const auto& f : found) {
        std::vector<std::int64_t> c;
        c.reserve(f.indices.size());
        for (const auto k : f.indices) c.push_back(finite.original[static_cast<size_t>(k)]);
        std::sort(c.begin(), c.end());
        clusters.push_back(std::move(c));
      }
    }
  }
  return cluster_list(clusters);
}

// Union-find with path halving over the pixels of the grid.
struct DisjointSets {
  std::vector<std::int32_t> parent;
  explicit DisjointSets(size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0); }
  std::int32_t find(std::int32_t a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  }
  void unite(std::int32_t a, std::int32_t b) {
    a = find(a);
    b = find(b);
    if (a != b) parent[std::max(a, b)] = std::min(a, b);
  }
};

py::list organized_clusters(const py::array& points, double max_distance, py::ssize_t min_points,
                            py::ssize_t max_points, double z_min, double z_max, bool diagonal) {
  const PointView v = point_view(points);
  if (points.ndim() != 3)
    throw std::invalid_argument("points must be an organized float32 array of shape (H, W, 3), got " +
                                describe(points));
  if (!(max_distance > 0)) throw std::invalid_argument("max_distance must be > 0 (metres)");
  check_cluster_sizes(min_points, max_points);
  if (v.size() >= std::numeric_limits<std::int32_t>::max())
    throw std::invalid_argument("points has too many pixels for organized_clusters, got " + describe(points));
  // The grid copied (contiguous, 12 bytes a pixel) with the GIL held, with which pixels take part.
  const py::ssize_t H = v.rows, W = v.cols;
  std::vector<Eigen::Vector3f> xyz(static_cast<size_t>(H * W));
  std::vector<std::uint8_t> in(static_cast<size_t>(H * W), 0);
  for (py::ssize_t r = 0; r < H; ++r)
    for (py::ssize_t c = 0; c < W; ++c) {
      const float x = v.coord(r, c, 0), y = v.coord(r, c, 1), z = v.coord(r, c, 2);
      const auto i = static_cast<size_t>(r * W + c);
      xyz[i] = Eigen::Vector3f(x, y, z);
      in[i] = std::isfinite(x) && std::isfinite(y) && std::isfinite(z) && z >= z_min && z <= z_max;
    }
  std::vector<std::vector<std::int64_t>> clusters;
  {
    py::gil_scoped_release nogil;
    const float d2 = static_cast<float>(max_distance * max_distance);
    DisjointSets sets(static_cast<size_t>(H * W));
    // Each pixel is joined to its already-visited neighbours: left, and the row above (up-left,
    // up, up-right with `diagonal`).
    for (py::ssize_t r = 0; r < H; ++r)
      for (py::ssize_t c = 0; c < W; ++c) {
        const py::ssize_t i = r * W + c;
        if (!in[static_cast<size_t>(i)]) continue;
        auto join = [&](py::ssize_t r1, py::ssize_t c1) {
          if (r1 < 0 || c1 < 0 || c1 >= W) return;
          const py::ssize_t j = r1 * W + c1;
          if (in[static_cast<size_t>(j)] &&
              (xyz[static_cast<size_t>(i)] - xyz[static_cast<size_t>(j)]).squaredNorm() <= d2)
            sets.unite(static_cast<std::int32_t>(i), static_cast<std::int32_t>(j));
        };
        join(r, c - 1);
        join(r - 1, c);
        if (diagonal) {
          join(r - 1, c - 1);
          join(r - 1, c + 1);
        }
      }
    std::vector<std::int32_t> size(static_cast<size_t>(H * W), 0);
    for (py::ssize_t i = 0; i < H * W; ++i)
      if (in[static_cast<size_t>(i)]) ++size[static_cast<size_t>(sets.find(static_cast<std::int32_t>(i)))];
    std::vector<std::int32_t> slot(static_cast<size_t>(H * W), -1);  // root -> cluster number
    for (py::ssize_t i = 0; i < H * W; ++i) {
      if (!in[static_cast<size_t>(i)]) continue;
      const auto root = static_cast<size_t>(sets.find(static_cast<std::int32_t>(i)));
      if (size[root] < min_points || size[root] > max_points) continue;
      if (slot[root] < 0) {
        slot[root] = static_cast<std::int32_t>(clusters.size());
        clusters.emplace_back();
        clusters.back().reserve(static_cast<size_t>(size[root]));
      }
      clusters[static_cast<size_t>(slot[root])].push_back(i);
    }
  }
  return cluster_list(clusters);
}

}  // namespace

void bind_segmentation(py::module_& m) {
  m.def("segment_plane", &segment_plane, py::arg("points"), py::arg("distance_threshold"),
        py::arg("max_iterations") = 1000, py::arg("axis") = py::none(), py::arg("eps_angle") = 0.2,
        py::arg("probability") = 0.99,
        R"doc(The dominant plane by RANSAC (pcl::SACSegmentation, coefficients refined by least squares).

points: float32 array of shape (N, 3) or (H, W, 3), any strides (metres), NaN points skipped.
distance_threshold: inlier distance (metres). axis: optional (x, y, z); when given the plane must
be perpendicular to it within eps_angle (radians) (SACMODEL_PERPENDICULAR_PLANE).
Returns (plane, inliers): float32 (4,) [nx, ny, nz, d] with n . p + d = 0, and int64 indices of
the inliers into the flattened input.
Raises ValueError when no plane is found.)doc");

  m.def("euclidean_clusters", &euclidean_clusters, py::arg("points"), py::arg("tolerance"),
        py::arg("min_points") = 1, py::arg("max_points") = std::numeric_limits<std::int32_t>::max(),
        py::arg("indices") = py::none(),
        R"doc(Clusters by pcl::EuclideanClusterExtraction (a k-d tree; points closer than tolerance join).

points: float32 array of shape (N, 3) or (H, W, 3), any strides (metres), NaN points skipped;
indices: optional int array of the points to cluster (into the flattened input); tolerance:
the largest gap within a cluster (metres); clusters with fewer than min_points or more than
max_points points are dropped.
Returns a list of int64 arrays of indices into the flattened input, one per cluster, largest
first, each sorted ascending.)doc");
  m.def("organized_clusters", &organized_clusters, py::arg("points"), py::arg("max_distance"),
        py::arg("min_points") = 1, py::arg("max_points") = std::numeric_limits<std::int32_t>::max(),
        py::arg("z_min") = -std::numeric_limits<double>::infinity(),
        py::arg("z_max") = std::numeric_limits<double>::infinity(), py::arg("diagonal") = true,
        R"doc(Connected components on the organized grid: neighbouring pixels join when their points are
within max_distance (metres, 3-D) of each other.

points: float32 array of shape (H, W, 3), any strides (metres); only finite points with
z_min <= z <= z_max take part (e.g. a cloud in a plane frame, banded above the table).
Neighbours are the 4 side pixels, and the 4 diagonal ones with `diagonal`. Components with
fewer than min_points or more than max_points points are dropped. One pass over the grid with
union-find: linear in H * W, no k-d tree.
Returns a list of int64 arrays of indices into the flattened (H * W) grid, one per cluster,
largest first, each sorted ascending.)doc");
}

}  // namespace example_pcl

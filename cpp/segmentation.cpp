// Model fitting by RANSAC through PCL's SACSegmentation.
#include <pcl/ModelCoefficients.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/sample_consensus/method_types.h>
#include <pcl/sample_consensus/model_types.h>
#include <pcl/segmentation/sac_segmentation.h>

#include <cmath>
#include <optional>

#include "common.hpp"

namespace example_pcl {
namespace {

py::tuple segment_plane(const py::array& points, double distance_threshold, int max_iterations,
                        std::optional<std::array<float, 3>> axis, double eps_angle, double probability) {
  const PointView v = point_view(points);
  if (!(distance_threshold > 0)) throw std::invalid_argument("distance_threshold must be > 0 (metres)");
  if (max_iterations < 1) throw std::invalid_argument("max_iterations must be >= 1");
  auto cloud = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  std::vector<std::int64_t> original;  // cloud index -> index into the flattened input
  pcl::ModelCoefficients coefficients;
  pcl::PointIndices inliers;
  {
    py::gil_scoped_release nogil;
    cloud->reserve(static_cast<size_t>(v.size()));
    original.reserve(static_cast<size_t>(v.size()));
    for (py::ssize_t i = 0; i < v.size(); ++i) {
      const float x = v.flat_coord(i, 0), y = v.flat_coord(i, 1), z = v.flat_coord(i, 2);
      if (!(std::isfinite(x) && std::isfinite(y) && std::isfinite(z))) continue;
      cloud->push_back(pcl::PointXYZ(x, y, z));
      original.push_back(i);
    }
    if (cloud->size() >= 3) {
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
      seg.setInputCloud(cloud);
      seg.segment(inliers, coefficients);
    }
  }
  if (cloud->size() < 3) throw std::invalid_argument("plane segmentation needs at least 3 finite points");
  if (inliers.indices.empty() || coefficients.values.size() != 4)
    throw std::invalid_argument("no plane found");
  py::array_t<float> plane(4);
  std::copy(coefficients.values.begin(), coefficients.values.end(), plane.mutable_data());
  py::array_t<std::int64_t> idx(static_cast<py::ssize_t>(inliers.indices.size()));
  auto* p = idx.mutable_data();
  for (size_t i = 0; i < inliers.indices.size(); ++i) p[i] = original[static_cast<size_t>(inliers.indices[i])];
  return py::make_tuple(plane, idx);
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
}

}  // namespace example_pcl

// Surface normals through PCL's NormalEstimation: the points are copied into a PCL cloud with the
// GIL held, and PCL works on that copy with the GIL released (common.hpp's GIL policy).
#include <pcl/features/normal_3d.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <cmath>
#include <optional>

#include "common.hpp"
#include "finite_cloud.hpp"

namespace example_pcl {
namespace {

py::tuple compute_point_normal(const py::array& points, std::optional<py::array> indices) {
  const PointView v = point_view(points);
  std::optional<py::array_t<std::int64_t>> idx;
  if (indices) idx = checked_indices(*indices, v.size());
  Eigen::Vector4f plane;
  float curvature = 0.f;
  bool ok = false;
  const FiniteCloud finite = finite_cloud(v, idx);  // the private copy, made with the GIL held
  const size_t n = finite.cloud->size();
  if (n < 3)
    throw std::invalid_argument("a normal needs at least 3 finite points, got " + std::to_string(n));
  {
    py::gil_scoped_release nogil;
    pcl::Indices all(n);
    for (size_t i = 0; i < n; ++i) all[i] = static_cast<pcl::index_t>(i);
    pcl::NormalEstimation<pcl::PointXYZ, pcl::Normal> estimator;
    ok = estimator.computePointNormal(*finite.cloud, all, plane, curvature);
  }
  if (!ok || !plane.allFinite()) throw std::invalid_argument("PCL could not fit a plane to the points");
  py::array_t<float> params(4);
  Eigen::Map<Eigen::Vector4f>(params.mutable_data()) = plane;
  return py::make_tuple(params, curvature);
}

}  // namespace

void bind_features(py::module_& m) {
  m.def("compute_point_normal", &compute_point_normal, py::arg("points"), py::arg("indices") = py::none(),
        R"doc(Least-squares plane of the finite points, by pcl::NormalEstimation::computePointNormal.

points: float32 array of shape (N, 3) or (H, W, 3), any strides (metres); indices: optional int
array of the points to use (into the flattened list). NaN and inf points are skipped.
Returns (plane, curvature): plane is float32 (4,) [nx, ny, nz, d] with the unit normal n and
n . p + d = 0 on the plane, its sign as PCL leaves it; curvature = l0 / (l0 + l1 + l2) of the
covariance's eigenvalues (0 for a perfect plane).
Raises ValueError with fewer than 3 finite points.)doc");
}

}  // namespace example_pcl

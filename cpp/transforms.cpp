// Rigid transforms, z filters, index extraction and centroids over float32 point arrays, read in
// place through PointView (no copy of the input, whatever its strides). Each is one pass over the
// points, so each runs with the GIL held (see the GIL policy in common.hpp).
#include <Eigen/Geometry>
#include <cmath>
#include <memory>
#include <optional>
#include <vector>

#include "common.hpp"

namespace example_pcl {
namespace {

Eigen::Affine3f checked_transform(const py::array& transform) {
  auto t = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(transform);
  if (!t || t.ndim() != 2 || t.shape(0) != 4 || t.shape(1) != 4)
    throw std::invalid_argument("transform must be a 4x4 homogeneous matrix, got " + describe(transform));
  Eigen::Matrix4d m = Eigen::Map<const Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(t.data());
  if (!m.allFinite()) throw std::invalid_argument("transform has NaN or inf entries");
  if (!m.row(3).isApprox(Eigen::RowVector4d(0, 0, 0, 1)))
    throw std::invalid_argument("transform's last row must be [0, 0, 0, 1]");
  return Eigen::Affine3f(m.cast<float>());
}

inline bool finite3(const PointView& v, py::ssize_t i) {
  return std::isfinite(v.flat_coord(i, 0)) && std::isfinite(v.flat_coord(i, 1)) && std::isfinite(v.flat_coord(i, 2));
}

template <typename Keep>
py::array_t<std::int64_t> indices_where(const py::array& points, Keep keep) {
  const PointView v = point_view(points);
  py::array_t<std::int64_t> out(v.size());  // uninitialised; shrunk to the kept count below
  std::int64_t* const first = out.mutable_data();
  std::int64_t* o = first;
  std::int64_t i = 0;
  for (py::ssize_t r = 0; r < v.rows; ++r) {
    const char* z = v.data + r * v.row_stride + 2 * v.coord_stride;
    for (py::ssize_t c = 0; c < v.cols; ++c, ++i, z += v.col_stride) {
      // Branch-free: write every index, advance only past the kept ones.
      *o = i;
      o += keep(*reinterpret_cast<const float*>(z));
    }
  }
  out.resize({static_cast<py::ssize_t>(o - first)}, false);
  return out;
}

py::array transform_cloud(const py::array& points, const py::array& transform, std::optional<py::array> out) {
  const PointView in = point_view(points);
  const Eigen::Affine3f T = checked_transform(transform);
  py::array result;
  if (out) {
    result = *out;
  } else {
    std::vector<py::ssize_t> shape = in.leading_shape;
    shape.push_back(3);
    result = py::array_t<float>(shape);
  }
  const PointView dst = point_view(result, true);
  if (dst.leading_shape != in.leading_shape)
    throw std::invalid_argument("out must have the shape of points, got " + describe(result) + " for " +
                                describe(points));
  const Eigen::Matrix3f R = T.linear();
  const Eigen::Vector3f t = T.translation();
  for (py::ssize_t r = 0; r < in.rows; ++r)
    for (py::ssize_t c = 0; c < in.cols; ++c) {
      // Read the whole point before writing: out may be points itself (in place).
      const Eigen::Vector3f p(in.coord(r, c, 0), in.coord(r, c, 1), in.coord(r, c, 2));
      const Eigen::Vector3f q = R * p + t;
      char* d = const_cast<char*>(dst.data) + r * dst.row_stride + c * dst.col_stride;
      for (int k = 0; k < 3; ++k) *reinterpret_cast<float*>(d + k * dst.coord_stride) = q[k];
    }
  return result;
}

py::array_t<float> extract(const py::array& points, const py::array& indices) {
  const PointView v = point_view(points);
  const auto idx = checked_indices(indices, v.size());
  py::array_t<float> out({idx.size(), static_cast<py::ssize_t>(3)});
  float* o = out.mutable_data();
  const std::int64_t* p = idx.data();
  for (py::ssize_t i = 0; i < idx.size(); ++i)
    for (int k = 0; k < 3; ++k) o[3 * i + k] = v.flat_coord(p[i], k);
  return out;
}

py::array_t<double> centroid(const py::array& points, std::optional<py::array> indices) {
  const PointView v = point_view(points);
  std::optional<py::array_t<std::int64_t>> idx;
  if (indices) idx = checked_indices(*indices, v.size());
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  py::ssize_t n = 0;
  const py::ssize_t count = idx ? idx->size() : v.size();
  for (py::ssize_t j = 0; j < count; ++j) {
    const py::ssize_t i = idx ? idx->data()[j] : j;
    if (!finite3(v, i)) continue;
    sum += Eigen::Vector3d(v.flat_coord(i, 0), v.flat_coord(i, 1), v.flat_coord(i, 2));
    ++n;
  }
  if (n == 0) throw std::invalid_argument("centroid of no finite points (" + describe(points) + ")");
  py::array_t<double> c(3);
  Eigen::Map<Eigen::Vector3d>(c.mutable_data()) = sum / static_cast<double>(n);
  return c;
}

py::array_t<float> squared_distances(const py::array& points, const py::array& center) {
  const PointView v = point_view(points);
  auto c = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(center);
  if (!c || c.ndim() != 1 || c.shape(0) != 3)
    throw std::invalid_argument("center must be 3 numbers (x, y, z), got " + describe(center));
  const Eigen::Vector3f ctr(c.data()[0], c.data()[1], c.data()[2]);
  py::array_t<float> out(v.leading_shape);
  float* o = out.mutable_data();
  for (py::ssize_t i = 0; i < v.size(); ++i) {
    const Eigen::Vector3f d(v.flat_coord(i, 0) - ctr[0], v.flat_coord(i, 1) - ctr[1], v.flat_coord(i, 2) - ctr[2]);
    o[i] = d.squaredNorm();  // NaN stays NaN; inf gives inf
  }
  return out;
}

}  // namespace

void bind_transforms(py::module_& m) {
  m.def("transform_cloud", &transform_cloud, py::arg("points"), py::arg("transform"), py::arg("out") = py::none(),
        R"doc(Applies a rigid transform to every point: q = R p + t.

points: float32 array of shape (N, 3) or (H, W, 3), any strides (a view of x, y, z inside a
    PointCloud2 buffer works without a copy). Metres.
transform: 4x4 homogeneous matrix (float64 or castable), last row [0, 0, 0, 1].
out: optional writable float32 array of the same shape to write into; pass points itself to
    transform in place. Default: a new contiguous array.
Returns out (or the new array). NaN points stay NaN.)doc");
  m.def("filter_z_band", [](const py::array& points, float z_nom, float eps) {
          if (!(eps >= 0)) throw std::invalid_argument("eps must be >= 0, got " + std::to_string(eps));
          return indices_where(points, [=](float z) { return std::fabs(z - z_nom) <= eps; });
        },
        py::arg("points"), py::arg("z_nom"), py::arg("eps"),
        R"doc(Indices of the points with |z - z_nom| <= eps (metres), as int64 into the flattened point list.

points: float32 array of shape (N, 3) or (H, W, 3), any strides. NaN points are never kept.)doc");
  m.def("filter_above_z", [](const py::array& points, float threshold) {
          return indices_where(points, [=](float z) { return z > threshold; });
        },
        py::arg("points"), py::arg("threshold"),
        R"doc(Indices of the points with z > threshold (metres), as int64 into the flattened point list.

points: float32 array of shape (N, 3) or (H, W, 3), any strides. NaN points are never kept.)doc");
  m.def("extract", &extract, py::arg("points"), py::arg("indices"),
        R"doc(The points at the given indices (into the flattened point list): float32 array of shape (K, 3).)doc");
  m.def("centroid", &centroid, py::arg("points"), py::arg("indices") = py::none(),
        R"doc(Mean of the finite points (NaN and inf skipped), optionally only of those at indices: float64 (3,).

Raises ValueError when there is no finite point.)doc");
  m.def("squared_distances", &squared_distances, py::arg("points"), py::arg("center"),
        R"doc(Squared distance (m^2) of every point from center: float32 array of the points' leading shape.

NaN points give NaN.)doc");
}

}  // namespace example_pcl

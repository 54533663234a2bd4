// example_pcl._native: thin pybind11 bindings over PCL and Eigen for example_pcl's per-point work.
// NumPy arrays in and out; the areas live one per file (io, transforms, features, segmentation),
// each following the GIL policy stated in common.hpp.
#include "common.hpp"

namespace example_pcl {

std::string describe(const py::array& a) {
  std::ostringstream s;
  s << py::str(a.dtype()).cast<std::string>() << " array of shape (";
  for (py::ssize_t i = 0; i < a.ndim(); ++i) s << (i ? ", " : "") << a.shape(i);
  s << (a.ndim() == 1 ? ",)" : ")");
  return s.str();
}

PointView point_view(const py::array& points, bool writable) {
  if (!py::dtype::of<float>().is(points.dtype()) && !points.dtype().equal(py::dtype::of<float>()))
    throw py::type_error("points must be a float32 array of shape (N, 3) or (H, W, 3), got " + describe(points));
  const auto nd = points.ndim();
  if ((nd != 2 && nd != 3) || points.shape(nd - 1) != 3)
    throw std::invalid_argument("points must be a float32 array of shape (N, 3) or (H, W, 3), got " +
                                describe(points));
  if (writable && !points.writeable())
    throw std::invalid_argument("points is read-only; pass a writable array to transform in place");
  PointView v;
  v.data = static_cast<const char*>(points.data());
  v.coord_stride = points.strides(nd - 1);
  if (nd == 2) {
    v.rows = 1;
    v.cols = points.shape(0);
    v.col_stride = points.strides(0);
    v.leading_shape = {points.shape(0)};
  } else {
    v.rows = points.shape(0);
    v.cols = points.shape(1);
    v.row_stride = points.strides(0);
    v.col_stride = points.strides(1);
    v.leading_shape = {points.shape(0), points.shape(1)};
  }
  return v;
}

py::array_t<std::int64_t> checked_indices(const py::array& indices, py::ssize_t n) {
  if (indices.ndim() != 1 || (indices.dtype().kind() != 'i' && indices.dtype().kind() != 'u'))
    throw py::type_error("indices must be a 1-D integer array, got " + describe(indices));
  auto idx = py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>::ensure(indices);
  const std::int64_t* p = idx.data();
  for (py::ssize_t i = 0; i < idx.size(); ++i)
    if (p[i] < 0 || p[i] >= n)
      throw std::invalid_argument("index " + std::to_string(p[i]) + " out of range for " + std::to_string(n) +
                                  " points");
  return idx;
}

}  // namespace example_pcl

PYBIND11_MODULE(_native, m) {
  m.doc() = "Thin bindings over PCL and Eigen for example_pcl: NumPy arrays in and out, metres throughout.";
  // package.xml's <version>, passed in by CMakeLists.txt.
  m.attr("__version__") = EXAMPLE_PCL_VERSION;
  example_pcl::bind_io(m);
  example_pcl::bind_transforms(m);
  example_pcl::bind_features(m);
  example_pcl::bind_segmentation(m);
}

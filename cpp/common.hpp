// Shared helpers of example_pcl._native: checking NumPy arrays at the boundary and reading them
// in place, whatever their strides.
//
// GIL policy, the one every binding follows:
//   The caller's arrays (and any other Python object) are read and written only while the GIL is
//   held. A binding checks its arguments (shape, dtype, range: TypeError / ValueError naming what
//   it got), then either
//   - does its work right there, GIL held, when it is one pass over the points (transform_cloud,
//     the z filters, extract, centroid, squared_distances): no copy, and a Kinect frame takes
//     about a millisecond, what the copy that would let it release the GIL costs anyway; or
//   - copies what it needs into private C++ containers (a pcl::PointCloud, std::vector, the PCD
//     writer's buffers), releases the GIL (py::gil_scoped_release) around the heavy work on those
//     copies only (PCL's RANSAC, k-d tree, normals, union-find, file reading and writing, LZF),
//     and takes it back before building the Python results.
//   So no other Python thread can change an array under a binding that is reading it (NumPy has
//   no locks: a torn read would be silent), and long work still lets other threads run (pcd_save
//   writes on several threads, find_can answers services while a cloud is processed).
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <Eigen/Core>
#include <cstdint>
#include <sstream>
#include <string>
#include <vector>

namespace example_pcl {

namespace py = pybind11;

// "float64 array of shape (5, 2)": the phrase every boundary error uses to name what it got.
std::string describe(const py::array& a);

// A read (or write) view of N points of 3 float32 coordinates anywhere in memory: an (N, 3) or
// (H, W, 3) array, contiguous or strided (e.g. the x, y, z fields inside a PointCloud2 buffer).
// Point (row r, column c) starts at data + r * row_stride + c * col_stride; coordinate k sits
// k * coord_stride bytes further. Strides are in bytes.
struct PointView {
  const char* data = nullptr;
  py::ssize_t rows = 0, cols = 0;  // (N, 3) arrays are viewed as rows = 1, cols = N
  py::ssize_t row_stride = 0, col_stride = 0, coord_stride = 0;
  std::vector<py::ssize_t> leading_shape;  // the shape without its trailing 3

  py::ssize_t size() const { return rows * cols; }
  const float* point(py::ssize_t r, py::ssize_t c) const {
    return reinterpret_cast<const float*>(data + r * row_stride + c * col_stride);
  }
  float coord(py::ssize_t r, py::ssize_t c, int k) const {
    return *reinterpret_cast<const float*>(data + r * row_stride + c * col_stride + k * coord_stride);
  }
  // Point number i of the flattened (row-major) point list.
  const char* flat(py::ssize_t i) const { return data + (i / cols) * row_stride + (i % cols) * col_stride; }
  float flat_coord(py::ssize_t i, int k) const {
    return *reinterpret_cast<const float*>(flat(i) + k * coord_stride);
  }
};

// Checks that `points` is a float32 array of shape (N, 3) or (H, W, 3) (raising TypeError for
// another dtype, ValueError for another shape) and returns a view of it; never copies. With
// `writable`, a read-only array raises ValueError.
PointView point_view(const py::array& points, bool writable = false);

// Checks `indices` is a 1-D integer array of point numbers below `n` (ValueError otherwise) and
// returns them as int64 (a copy only when the dtype differs).
py::array_t<std::int64_t> checked_indices(const py::array& indices, py::ssize_t n);

void bind_io(py::module_& m);  // PCD files; the binary_compressed body is made in pcd_compressed.cpp
void bind_transforms(py::module_& m);
void bind_features(py::module_& m);
void bind_segmentation(py::module_& m);

}  // namespace example_pcl

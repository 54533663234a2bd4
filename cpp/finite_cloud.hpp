// The finite points of a NumPy point array copied into a PCL cloud: the private copy the PCL
// bindings (features.cpp, segmentation.cpp) make with the GIL held before releasing it.
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <cmath>
#include <memory>
#include <optional>
#include <vector>

#include "common.hpp"

namespace example_pcl {

// The finite points of `v` (optionally only those at `idx`) as a PCL cloud, with each cloud
// point's index into the flattened input. NaN and inf points are left out.
struct FiniteCloud {
  std::shared_ptr<pcl::PointCloud<pcl::PointXYZ>> cloud = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  std::vector<std::int64_t> original;  // cloud index -> index into the flattened input
};

inline FiniteCloud finite_cloud(const PointView& v,
                                const std::optional<py::array_t<std::int64_t>>& idx = std::nullopt) {
  FiniteCloud out;
  const py::ssize_t count = idx ? idx->size() : v.size();
  out.cloud->reserve(static_cast<size_t>(count));
  out.original.reserve(static_cast<size_t>(count));
  for (py::ssize_t j = 0; j < count; ++j) {
    const py::ssize_t i = idx ? idx->data()[j] : j;
    const float x = v.flat_coord(i, 0), y = v.flat_coord(i, 1), z = v.flat_coord(i, 2);
    if (!(std::isfinite(x) && std::isfinite(y) && std::isfinite(z))) continue;
    out.cloud->push_back(pcl::PointXYZ(x, y, z));
    out.original.push_back(i);
  }
  return out;
}

}  // namespace example_pcl

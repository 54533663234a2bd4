// PCL's own cylinder segmentation, timed: the reference example_pcl.auto_finder is compared with.
// It follows PCL's cylinder_segmentation tutorial step by step: PassThrough on z, NormalEstimation
// (k-d tree, k = 50), SACSegmentationFromNormals for the plane (normal distance weight 0.1,
// 100 iterations, 0.03 m), extract the rest, then SACSegmentationFromNormals with SACMODEL_CYLINDER
// (weight 0.1, 10000 iterations, 0.05 m, radius 0..0.1 m). One addition: between the two, only
// points 0.01-0.4 m above the plane are kept (our scenes show the floor and the table's edge,
// the tutorial's does not). The tutorial finds one cylinder; here the cylinder step is repeated up to MAX_CYLINDERS times, each time removing the previous
// cylinder's inliers (and their normals) and searching again.
//
// Usage: pcl_cylinder_segmentation INPUT.pcd MAX_CYLINDERS [Z_MAX]
// The cylinder step runs twice on the same normals: with the tutorial's parameters, and "tuned"
// for soda cans (0.01 m threshold, radius 0.015..0.08 m).
// Prints one JSON object: {"points", "plane": [a, b, c, d], "seconds": {"passthrough", "normals",
// "plane"}, "runs": [{"name", "distance_threshold", "radius_limits", "cylinders": [{"point_on_axis",
// "axis", "radius", "inliers"}...], "seconds": {"cylinders", "total"}}...]} (loading is not timed;
// a run's total includes the shared passthrough, normals and plane).
#include <pcl/ModelCoefficients.h>
#include <pcl/features/normal_3d.h>
#include <pcl/filters/extract_indices.h>
#include <pcl/filters/passthrough.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>
#include <pcl/sample_consensus/method_types.h>
#include <pcl/sample_consensus/model_types.h>
#include <pcl/search/kdtree.h>
#include <pcl/segmentation/sac_segmentation.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>

using PointT = pcl::PointXYZ;
using Clock = std::chrono::steady_clock;

static double since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

int main(int argc, char** argv) {
  if (argc < 3 || argc > 4) {
    std::fprintf(stderr, "usage: %s INPUT.pcd MAX_CYLINDERS [Z_MAX]\n", argv[0]);
    return 2;
  }
  const int max_cylinders = std::atoi(argv[2]);
  const float z_max = argc == 4 ? static_cast<float>(std::atof(argv[3])) : 3.0f;
  auto cloud = std::make_shared<pcl::PointCloud<PointT>>();
  if (pcl::io::loadPCDFile<PointT>(argv[1], *cloud) < 0) {
    std::fprintf(stderr, "cannot read %s\n", argv[1]);
    return 1;
  }
  const auto t0 = Clock::now();

  // Build a passthrough filter to remove spurious NaNs (and points beyond z_max).
  auto filtered = std::make_shared<pcl::PointCloud<PointT>>();
  pcl::PassThrough<PointT> pass;
  pass.setInputCloud(cloud);
  pass.setFilterFieldName("z");
  pass.setFilterLimits(0, z_max);
  pass.filter(*filtered);
  const double t_pass = since(t0);

  // Estimate point normals.
  auto t = Clock::now();
  auto tree = std::make_shared<pcl::search::KdTree<PointT>>();
  auto normals = std::make_shared<pcl::PointCloud<pcl::Normal>>();
  pcl::NormalEstimation<PointT, pcl::Normal> ne;
  ne.setSearchMethod(tree);
  ne.setInputCloud(filtered);
  ne.setKSearch(50);
  ne.compute(*normals);
  const double t_normals = since(t);

  // Create the segmentation object for the planar model and set all the parameters.
  t = Clock::now();
  pcl::SACSegmentationFromNormals<PointT, pcl::Normal> seg;
  auto inliers_plane = std::make_shared<pcl::PointIndices>();
  pcl::ModelCoefficients plane;
  seg.setOptimizeCoefficients(true);
  seg.setModelType(pcl::SACMODEL_NORMAL_PLANE);
  seg.setNormalDistanceWeight(0.1);
  seg.setMethodType(pcl::SAC_RANSAC);
  seg.setMaxIterations(100);
  seg.setDistanceThreshold(0.03);
  seg.setInputCloud(filtered);
  seg.setInputNormals(normals);
  seg.segment(*inliers_plane, plane);

  // Remove the planar inliers, extract the rest. The tutorial's scene holds little but the table
  // and the mug; ours also hold the floor and the table's edge, which the cylinder RANSAC (0.05 m
  // threshold) happily fits. So, as PCL's tabletop pipelines do (ExtractPolygonalPrismData), only
  // what stands on the plane is kept: points on the sensor's side of it, 0.01 to 0.4 m above it.
  auto rest = std::make_shared<pcl::PointCloud<PointT>>();
  auto rest_normals = std::make_shared<pcl::PointCloud<pcl::Normal>>();
  if (plane.values.size() == 4) {
    Eigen::Vector4f p(plane.values[0], plane.values[1], plane.values[2], plane.values[3]);
    if (p[3] < 0) p = -p;  // the sensor (origin) on the positive side: n . 0 + d > 0
    for (size_t i = 0; i < filtered->size(); ++i) {
      const auto& q = (*filtered)[i];
      const float h = p[0] * q.x + p[1] * q.y + p[2] * q.z + p[3];
      if (h > 0.01f && h < 0.4f) {
        rest->push_back(q);
        rest_normals->push_back((*normals)[i]);
      }
    }
  }
  pcl::ExtractIndices<PointT> extract;
  pcl::ExtractIndices<pcl::Normal> extract_normals;
  extract.setNegative(true);
  extract_normals.setNegative(true);
  const double t_plane = since(t);

  // Create the segmentation object for cylinder segmentation and set all the parameters; repeat
  // on what is left after each cylinder. Two parameter sets on the same normals: the tutorial's,
  // and one tightened for soda cans.
  struct Variant {
    const char* name;
    double distance_threshold, radius_min, radius_max;
  };
  const Variant variants[] = {{"tutorial", 0.05, 0.0, 0.1}, {"tuned", 0.01, 0.015, 0.08}};
  std::printf("{\"points\": %zu, \"plane\": [", filtered->size());
  for (size_t i = 0; i < plane.values.size(); ++i) std::printf("%s%.7g", i ? ", " : "", plane.values[i]);
  std::printf("], \"seconds\": {\"passthrough\": %.6f, \"normals\": %.6f, \"plane\": %.6f}, \"runs\": [",
              t_pass, t_normals, t_plane);
  bool first_variant = true;
  for (const auto& variant : variants) {
    t = Clock::now();
    auto left = rest;
    auto left_normals = rest_normals;
    std::string cylinders;
    for (int k = 0; k < max_cylinders && left->size() >= 10; ++k) {
      pcl::SACSegmentationFromNormals<PointT, pcl::Normal> cyl;
      auto inliers = std::make_shared<pcl::PointIndices>();
      pcl::ModelCoefficients c;
      cyl.setOptimizeCoefficients(true);
      cyl.setModelType(pcl::SACMODEL_CYLINDER);
      cyl.setMethodType(pcl::SAC_RANSAC);
      cyl.setNormalDistanceWeight(0.1);
      cyl.setMaxIterations(10000);
      cyl.setDistanceThreshold(variant.distance_threshold);
      cyl.setRadiusLimits(variant.radius_min, variant.radius_max);
      cyl.setInputCloud(left);
      cyl.setInputNormals(left_normals);
      cyl.segment(*inliers, c);
      if (inliers->indices.empty() || c.values.size() != 7) break;
      char buf[512];
      std::snprintf(buf, sizeof buf,
                    "%s{\"point_on_axis\": [%.7g, %.7g, %.7g], \"axis\": [%.7g, %.7g, %.7g], \"radius\": %.7g, "
                    "\"inliers\": %zu}",
                    cylinders.empty() ? "" : ", ", c.values[0], c.values[1], c.values[2], c.values[3], c.values[4],
                    c.values[5], c.values[6], inliers->indices.size());
      cylinders += buf;
      auto next = std::make_shared<pcl::PointCloud<PointT>>();
      auto next_normals = std::make_shared<pcl::PointCloud<pcl::Normal>>();
      extract.setInputCloud(left);
      extract.setIndices(inliers);
      extract.filter(*next);
      extract_normals.setInputCloud(left_normals);
      extract_normals.setIndices(inliers);
      extract_normals.filter(*next_normals);
      left = next;
      left_normals = next_normals;
    }
    const double t_cylinders = since(t);
    std::printf("%s{\"name\": \"%s\", \"distance_threshold\": %g, \"radius_limits\": [%g, %g], \"cylinders\": [%s], "
                "\"seconds\": {\"cylinders\": %.6f, \"total\": %.6f}}",
                first_variant ? "" : ", ", variant.name, variant.distance_threshold, variant.radius_min,
                variant.radius_max, cylinders.c_str(), t_cylinders, t_pass + t_normals + t_plane + t_cylinders);
    first_variant = false;
  }
  std::printf("]}\n");
  return 0;
}

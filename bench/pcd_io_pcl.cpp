// PCL's own PCD I/O, timed: the reference the Python path (example_pcl.pcd) is compared with.
// Usage: pcd_io_pcl INPUT.pcd OUT_DIR REPEATS
// Prints one JSON object: median seconds of loadPCDFile (pcl::PCLPointCloud2) for INPUT and of
// savePCDFile in each format, then of reading each written file back.
#include <pcl/PCLPointCloud2.h>
#include <pcl/io/pcd_io.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

static double median_seconds(int repeats, const std::function<void()>& f) {
  std::vector<double> t;
  for (int i = 0; i < repeats; ++i) {
    const auto start = std::chrono::steady_clock::now();
    f();
    t.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

int main(int argc, char** argv) {
  if (argc != 4) {
    std::fprintf(stderr, "usage: %s INPUT.pcd OUT_DIR REPEATS\n", argv[0]);
    return 2;
  }
  const std::string input = argv[1], out_dir = argv[2];
  const int repeats = std::max(1, std::atoi(argv[3]));
  pcl::PCLPointCloud2 cloud;
  if (pcl::io::loadPCDFile(input, cloud) < 0) return 1;
  const Eigen::Vector4f origin = Eigen::Vector4f::Zero();
  const Eigen::Quaternionf orientation = Eigen::Quaternionf::Identity();
  pcl::PCDWriter writer;
  std::printf("{\"points\": %u", cloud.width * cloud.height);
  const char* formats[] = {"ascii", "binary", "binary_compressed"};
  for (int f = 0; f < 3; ++f) {
    const std::string path = out_dir + "/pcl_" + formats[f] + ".pcd";
    const double write = median_seconds(repeats, [&] {
      if (f == 0) writer.writeASCII(path, cloud, origin, orientation, 9);
      else if (f == 1) writer.writeBinary(path, cloud, origin, orientation);
      else writer.writeBinaryCompressed(path, cloud, origin, orientation);
    });
    const double read = median_seconds(repeats, [&] {
      pcl::PCLPointCloud2 back;
      pcl::io::loadPCDFile(path, back);
    });
    std::printf(", \"write_%s\": %.6f, \"read_%s\": %.6f", formats[f], write, formats[f], read);
  }
  std::printf("}\n");
  return 0;
}

// PCD files through PCL's own reader and writer (pcl::PCDReader / pcl::PCDWriter on
// pcl::PCLPointCloud2), so every field, the organized width x height and the viewpoint are kept
// exactly as PCL keeps them. binary_compressed is the one body made here rather than by PCL
// (PCL's header, PCL's lzfCompress, PCL's layout; see pcd_compressed.cpp). The Python side
// (example_pcl.pcd) turns the raw buffer and field list into a NumPy structured array.
#include <pcl/PCLPointCloud2.h>
#include <pcl/io/pcd_io.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <fcntl.h>
#include <limits>
#include <sys/stat.h>
#include <unistd.h>

#include <utility>
#include <vector>

#include "common.hpp"
#include "pcd_compressed.hpp"

namespace example_pcl {
namespace {

constexpr int kAscii = 0, kBinary = 1, kBinaryCompressed = 2;

// Writes the pieces to path with plain checked write()s; "" on success, else why not (errno).
std::string write_file(const std::string& path, const std::vector<std::pair<const char*, size_t>>& pieces) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
  if (fd < 0) return std::strerror(errno);
  for (const auto& [data, size] : pieces) {
    size_t done = 0;
    while (done < size) {
      const ssize_t n = ::write(fd, data + done, size - done);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) {
        const std::string why = n < 0 ? std::strerror(errno) : "short write";
        ::close(fd);
        return why;
      }
      done += static_cast<size_t>(n);
    }
  }
  if (::close(fd) != 0) return std::strerror(errno);
  return "";
}

// PCL's writeASCII does not check its stream: on a full disk it leaves a cut file and reports
// success. A complete file ends with a newline after every one of its points.
std::string check_ascii_complete(const std::string& path, std::uint64_t points) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::strerror(errno);
  std::uint64_t newlines = 0, header_lines = 0;
  std::string line;
  while (std::getline(in, line)) {
    ++newlines;
    if (header_lines == 0 && line.rfind("DATA ", 0) == 0) header_lines = newlines;
  }
  if (header_lines == 0 || newlines != header_lines + points)
    return "the file is incomplete (" + std::to_string(newlines - header_lines) + " of " + std::to_string(points) +
           " points written; disk full?)";
  return "";
}

py::list fields_to_python(const std::vector<pcl::PCLPointField>& fields) {
  py::list out;
  for (const auto& f : fields)
    out.append(py::make_tuple(f.name, f.offset, static_cast<int>(f.datatype), f.count));
  return out;
}

std::string file_error(const std::string& path, const std::string& why) {
  return "cannot read PCD file '" + path + "': " + why;
}

// PCL trusts the header's point count and the compressed block's sizes; a truncated or forged file
// would make it read past the end of its mapping or allocate without bound. Check them first.
void check_body_fits(const std::string& path, const pcl::PCLPointCloud2& header, int data_type,
                     unsigned int data_idx) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) throw std::invalid_argument(file_error(path, std::strerror(errno)));
  const std::uint64_t file_size = static_cast<std::uint64_t>(st.st_size);
  const std::uint64_t points = static_cast<std::uint64_t>(header.width) * header.height;
  const std::uint64_t body = points * header.point_step;
  if (header.fields.empty() || header.point_step == 0)
    throw std::invalid_argument(file_error(path, "no FIELDS in the header"));
  if (data_idx > file_size) throw std::invalid_argument(file_error(path, "header runs past the end of the file"));
  const std::uint64_t remaining = file_size - data_idx;
  if (data_type == kBinary) {
    if (remaining < body)
      throw std::invalid_argument(file_error(path, "truncated: " + std::to_string(points) + " points need " +
                                                       std::to_string(body) + " bytes of data, the file has " +
                                                       std::to_string(remaining)));
  } else if (data_type == kBinaryCompressed) {
    if (points == 0) return;
    if (remaining < 8) throw std::invalid_argument(file_error(path, "truncated: no compressed block"));
    std::uint32_t sizes[2] = {0, 0};
    std::ifstream in(path, std::ios::binary);
    in.seekg(data_idx);
    in.read(reinterpret_cast<char*>(sizes), sizeof(sizes));
    if (!in) throw std::invalid_argument(file_error(path, "cannot read the compressed block's sizes"));
    if (sizes[0] > remaining - 8)
      throw std::invalid_argument(file_error(path, "truncated: compressed block of " + std::to_string(sizes[0]) +
                                                       " bytes, the file has " + std::to_string(remaining - 8)));
    if (sizes[1] != body)
      throw std::invalid_argument(file_error(path, "compressed block unpacks to " + std::to_string(sizes[1]) +
                                                       " bytes, the header's points need " + std::to_string(body)));
  } else {
    // ASCII: every point takes at least one character and a separator per value.
    std::uint64_t values = 0;
    for (const auto& f : header.fields) values += f.count;
    if (points * std::max<std::uint64_t>(values, 1) * 2 > remaining + 1)
      throw std::invalid_argument(file_error(path, "truncated: the header announces " + std::to_string(points) +
                                                       " points, the file is too short to hold them"));
    // A cut inside the last number still parses; every writer ends the last point with a newline.
    if (points > 0 && file_size > 0) {
      std::ifstream in(path, std::ios::binary);
      in.seekg(static_cast<std::streamoff>(file_size - 1));
      char last = 0;
      in.get(last);
      if (last != '\n' && last != '\r' && last != ' ' && last != '\t')
        throw std::invalid_argument(file_error(path, "truncated: the last line has no end (cut off?)"));
    }
  }
}

py::dict read_pcd(const std::string& path) {
  pcl::PCDReader reader;
  auto cloud = std::make_unique<pcl::PCLPointCloud2>();
  Eigen::Vector4f origin;
  Eigen::Quaternionf orientation;
  int version = 0, data_type = 0;
  unsigned int data_idx = 0;
  int rc = 0;
  {
    py::gil_scoped_release nogil;
    try {
      std::ifstream probe(path);
      if (!probe) throw std::invalid_argument(file_error(path, std::strerror(errno)));
      rc = reader.readHeader(path, *cloud, origin, orientation, version, data_type, data_idx);
      if (rc < 0) throw std::invalid_argument(file_error(path, "not a valid PCD header (PCL's readHeader failed)"));
      check_body_fits(path, *cloud, data_type, data_idx);
      // PCL's read() crashes on some files without points (an empty file passes readHeader);
      // the header already holds everything an empty cloud has.
      if (static_cast<std::uint64_t>(cloud->width) * cloud->height > 0)
        rc = reader.read(path, *cloud, origin, orientation, version);
      else
        cloud->data.clear();
    } catch (const std::invalid_argument&) {
      throw;
    } catch (const std::exception& e) {
      throw std::invalid_argument(file_error(path, e.what()));
    }
  }
  if (rc < 0) throw std::invalid_argument(file_error(path, "PCL's reader rejected the data (code " + std::to_string(rc) + ")"));
  for (const auto& f : cloud->fields)
    for (const unsigned char ch : f.name)
      if (ch < 0x21 || ch > 0x7e)
        throw std::invalid_argument(file_error(path, "a field name is not printable ASCII"));
  if (cloud->data.size() != static_cast<size_t>(cloud->width) * cloud->height * cloud->point_step)
    throw std::invalid_argument(file_error(path, "data size does not match width x height x point size"));

  // The NumPy buffer takes over PCL's data vector: no copy.
  auto* owned = new std::vector<std::uint8_t>(std::move(cloud->data));
  py::capsule free_when_done(owned, [](void* p) { delete static_cast<std::vector<std::uint8_t>*>(p); });
  py::array_t<std::uint8_t> data({static_cast<py::ssize_t>(owned->size())}, {1}, owned->data(), free_when_done);

  py::dict out;
  out["data"] = data;
  out["fields"] = fields_to_python(cloud->fields);
  out["width"] = cloud->width;
  out["height"] = cloud->height;
  out["point_step"] = cloud->point_step;
  out["is_dense"] = static_cast<bool>(cloud->is_dense);
  out["origin"] = py::make_tuple(origin[0], origin[1], origin[2]);
  out["orientation"] = py::make_tuple(orientation.w(), orientation.x(), orientation.y(), orientation.z());
  out["version"] = version;
  out["format"] = data_type == kAscii ? "ascii" : data_type == kBinary ? "binary" : "binary_compressed";
  return out;
}

void write_pcd(const std::string& path, const py::buffer& data, const py::list& fields, std::uint32_t width,
               std::uint32_t height, std::uint32_t point_step, bool is_dense, const std::array<float, 3>& origin,
               const std::array<float, 4>& orientation, const std::string& format, int precision, int threads) {
  pcl::PCLPointCloud2 cloud;
  cloud.width = width;
  cloud.height = height;
  cloud.point_step = point_step;
  cloud.row_step = width * point_step;
  cloud.is_dense = is_dense;
  for (const auto& item : fields) {
    const auto t = item.cast<py::tuple>();
    if (t.size() != 4) throw std::invalid_argument("each field must be (name, offset, datatype, count)");
    pcl::PCLPointField f;
    f.name = t[0].cast<std::string>();
    f.offset = t[1].cast<std::uint32_t>();
    f.datatype = t[2].cast<std::uint8_t>();
    f.count = t[3].cast<std::uint32_t>();
    if (f.datatype < 1 || f.datatype > 8)
      throw std::invalid_argument("field '" + f.name + "' has unknown datatype " + std::to_string(f.datatype));
    if (f.offset + f.count * pcl::getFieldSize(f.datatype) > point_step)
      throw std::invalid_argument("field '" + f.name + "' runs past point_step " + std::to_string(point_step));
    cloud.fields.push_back(f);
  }
  const py::buffer_info buf = data.request();
  py::ssize_t contiguous_stride = buf.itemsize;
  for (py::ssize_t d = buf.ndim - 1; d >= 0; --d) {
    if (buf.shape[d] > 1 && buf.strides[d] != contiguous_stride)
      throw std::invalid_argument("data must be a C-contiguous buffer (e.g. points.view(np.uint8) of a contiguous "
                                  "array), got strides that skip bytes");
    contiguous_stride *= buf.shape[d];
  }
  const size_t nbytes = static_cast<size_t>(buf.size) * buf.itemsize;
  if (nbytes != static_cast<size_t>(width) * height * point_step)
    throw std::invalid_argument("data has " + std::to_string(nbytes) + " bytes, width x height x point_step is " +
                                std::to_string(static_cast<size_t>(width) * height * point_step));
  if (format != "ascii" && format != "binary" && format != "binary_compressed")
    throw std::invalid_argument("format must be ascii, binary or binary_compressed, got '" + format + "'");
  if (threads < 0)
    throw std::invalid_argument("threads must be >= 0 (0 = one chunk per core), got " + std::to_string(threads));
  const Eigen::Vector4f o(origin[0], origin[1], origin[2], 0.f);
  const Eigen::Quaternionf q(orientation[0], orientation[1], orientation[2], orientation[3]);
  const auto* bytes = static_cast<const std::uint8_t*>(buf.ptr);
  const size_t points = static_cast<size_t>(width) * height;
  Bytes field_major;
  if (format == "binary_compressed") {
    std::vector<FieldBytes> kept;
    size_t point_bytes = 0;
    for (const auto& f : cloud.fields) {
      if (f.name == "_") continue;  // padding, as PCL leaves it out
      kept.push_back({f.offset, f.count * static_cast<size_t>(pcl::getFieldSize(f.datatype))});
      point_bytes += kept.back().size;
    }
    if (points * point_bytes > std::numeric_limits<std::uint32_t>::max())
      throw std::invalid_argument(std::to_string(points * point_bytes) +
                                  " bytes of points do not fit binary_compressed's 32-bit size");
    // Gathered with the GIL held, so no other Python thread changes the points meanwhile; this
    // replaces the copy into cloud.data the other formats make.
    field_major = to_field_major(bytes, points, point_step, kept);
  } else {
    cloud.data.assign(bytes, bytes + nbytes);
  }
  std::string error;
  {
    py::gil_scoped_release nogil;
    pcl::PCDWriter writer;
    try {
      if (format == "ascii") {
        if (writer.writeASCII(path, cloud, o, q, precision) < 0)
          error = "PCL's writeASCII failed";
        else
          error = check_ascii_complete(path, static_cast<std::uint64_t>(width) * height);
      } else if (format == "binary") {
        // PCL's writeBinary fills an mmap of a file it sized with fallocate, which on some file
        // systems (tmpfs) does not reserve the space: a full disk then kills the process with
        // SIGBUS. The same header, then the data with checked write()s.
        std::string header = writer.generateHeaderBinary(cloud, o, q) + "DATA binary\n";
        error = write_file(path, {{header.data(), header.size()},
                                  {reinterpret_cast<const char*>(cloud.data.data()), cloud.data.size()}});
      } else {
        // PCL's header, then the body compressed here (see compress_body), written as above.
        const std::string header = writer.generateHeaderBinaryCompressed(cloud, o, q) + "DATA binary_compressed\n";
        const auto body = compress_body(field_major, static_cast<size_t>(threads), error);
        if (error.empty()) {
          std::vector<std::pair<const char*, size_t>> pieces{{header.data(), header.size()}};
          for (const auto& piece : body) pieces.emplace_back(reinterpret_cast<const char*>(piece.data()), piece.size());
          error = write_file(path, pieces);
        }
      }
    } catch (const std::exception& e) {
      error = e.what();
    }
  }
  if (!error.empty()) throw std::runtime_error("cannot write PCD file '" + path + "': " + error);
}

}  // namespace

void bind_io(py::module_& m) {
  m.def("read_pcd", &read_pcd, py::arg("path"),
        R"doc(Reads a PCD file (v0.5-0.7; ascii, binary or binary_compressed) with pcl::PCDReader.

Returns a dict: data (uint8 array, the points' bytes, row-major, point_step bytes each, owned by
the array, not copied), fields (list of (name, offset, datatype, count), datatype as in
sensor_msgs/PointField), width, height, point_step, is_dense, origin (x, y, z in metres),
orientation (w, x, y, z quaternion), version and format.
Raises ValueError naming the file when it is missing, truncated or malformed.)doc");
  m.def("write_pcd", &write_pcd, py::arg("path"), py::arg("data"), py::arg("fields"), py::arg("width"),
        py::arg("height"), py::arg("point_step"), py::arg("is_dense"), py::arg("origin"), py::arg("orientation"),
        py::arg("format") = "binary", py::arg("precision") = 9, py::arg("threads") = 0,
        R"doc(Writes a PCD v0.7 file in PCL's format: ascii, binary or binary_compressed.

data: any buffer of width * height * point_step bytes; fields: list of (name, offset, datatype,
count); origin: (x, y, z) metres; orientation: (w, x, y, z); format: "ascii", "binary" or
"binary_compressed"; precision: significant digits of floats in ascii; threads: binary_compressed
compresses in this many chunks (0 = one per core, no chunk under 256 KiB) on at most
min(cores, chunks, 8) threads; any value gives a file PCL reads to the same points.
Headers are PCL's (generateHeaderBinary, generateHeaderBinaryCompressed); ascii is PCL's
writeASCII; the binary_compressed body is PCL's layout compressed with PCL's lzfCompress. The
bytes go out with checked write()s, so a full disk is an error, never a crash or a cut file.
Writes straight to path: callers wanting an atomic file write to a temporary name and rename.
Raises ValueError for inconsistent arguments, RuntimeError when the file cannot be written.)doc");
}

}  // namespace example_pcl

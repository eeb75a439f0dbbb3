// Mesh file dispatch: whole-file reads and writes, format by extension. The format parsers live in
// ply_io.cpp, obj_io.cpp and off_io.cpp.
#include "core/mesh_io.h"

#include <sys/stat.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <vector>

#include "core/files.h"
#include "core/mesh_io_internal.h"

namespace rangebayes {
namespace mesh_io {

bool TextCursor::ParseOutOfRange(const char* start, double* value) {
  const char* stop = start;
  while (stop < end_ && !IsSpace(*stop)) ++stop;
  const std::string token(start, stop);  // whole: a cut token can read as another number (1e-000…0400 as 1)
  char* parsed_end = nullptr;
  const double parsed = std::strtod(token.c_str(), &parsed_end);
  if (parsed_end != token.c_str() + token.size()) return false;
  *value = parsed;
  p_ = stop;
  return true;
}

void AppendDouble(std::string* out, double value, int precision) {
  char buffer[64];
  std::to_chars_result result{};
  // Shortest form that reads back to the same double: exact round trips with fewer bytes than %.17g.
  if (precision >= 17) {
    result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  } else {
    result = std::to_chars(buffer, buffer + sizeof(buffer), value, std::chars_format::general,
                           std::max(1, precision));
  }
  out->append(buffer, result.ptr);
}

void AppendInt(std::string* out, int64_t value) {
  char buffer[24];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  out->append(buffer, result.ptr);
}

namespace {

// Triangulates a simple polygon (corner indices into xyz, three doubles a vertex) by ear clipping in the plane of
// its Newell normal; the triangles keep the polygon's winding. Returns false (and leaves `out` alone) when the
// polygon is convex (its fan is as good), degenerate, or not simple (no ear found): the fan stays. `out` gets
// n − 2 triangles as positions in `corners` (0..n-1).
bool EarClip(const double* xyz, const int* corners, size_t n, std::vector<size_t>* out) {
  const auto V = [xyz](int v) { return Eigen::Map<const Eigen::Vector3d>(xyz + 3 * static_cast<size_t>(v)); };
  Eigen::Vector3d normal = Eigen::Vector3d::Zero(), centre = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d a = V(corners[i]), b = V(corners[(i + 1) % n]);
    normal += a.cross(b);
    centre += a;
  }
  const double area2 = normal.norm();  // twice the polygon's area
  if (!(area2 > 0) || !std::isfinite(area2)) return false;
  normal /= area2;
  centre /= static_cast<double>(n);
  const Eigen::Vector3d u = normal.unitOrthogonal(), w = normal.cross(u);
  std::vector<Eigen::Vector2d> p(n);
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d d = V(corners[i]) - centre;
    p[i] = {d.dot(u), d.dot(w)};  // counter-clockwise: (u, w, normal) is right-handed
  }
  const auto turn = [](const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
    return (b - a).x() * (c - b).y() - (b - a).y() * (c - b).x();
  };
  const double tolerance = 1e-12 * area2;
  bool convex = true;
  for (size_t i = 0; i < n && convex; ++i) convex = turn(p[(i + n - 1) % n], p[i], p[(i + 1) % n]) >= -tolerance;
  if (convex) return false;
  std::vector<size_t> ring(n);
  for (size_t i = 0; i < n; ++i) ring[i] = i;
  std::vector<size_t> triangles;
  triangles.reserve(3 * (n - 2));
  while (ring.size() > 3) {
    bool clipped = false;
    for (size_t k = 0; k < ring.size() && !clipped; ++k) {
      const size_t a = ring[(k + ring.size() - 1) % ring.size()], b = ring[k], c = ring[(k + 1) % ring.size()];
      if (turn(p[a], p[b], p[c]) <= tolerance) continue;  // reflex or flat corner: no ear
      bool empty = true;
      for (const size_t q : ring) {
        if (q == a || q == b || q == c) continue;
        if (turn(p[a], p[b], p[q]) >= 0 && turn(p[b], p[c], p[q]) >= 0 && turn(p[c], p[a], p[q]) >= 0) {
          empty = false;
          break;
        }
      }
      if (!empty) continue;
      triangles.insert(triangles.end(), {a, b, c});
      ring.erase(ring.begin() + static_cast<std::ptrdiff_t>(k));
      clipped = true;
    }
    if (!clipped) return false;
  }
  triangles.insert(triangles.end(), {ring[0], ring[1], ring[2]});
  *out = std::move(triangles);
  return true;
}

}  // namespace

void PolygonSplitter::Add(const int* corners, const int* corner_attributes, size_t n, std::vector<int>* triangles,
                          std::vector<int>* attributes, const double* xyz, size_t num_vertices) {
  const size_t first = triangles->size() / 3;
  ++count_;
  for (size_t c = 1; c + 1 < n; ++c) {
    for (const size_t k : {size_t{0}, c, c + 1}) {
      triangles->push_back(corners[k]);
      if (attributes != nullptr) attributes->push_back(corner_attributes[k]);
    }
  }
  if (std::all_of(corners, corners + n,
                  [num_vertices](int v) { return v >= 0 && static_cast<size_t>(v) < num_vertices; })) {
    Replace(xyz, corners, corner_attributes, n, first, triangles, attributes);
    return;
  }
  // A corner not read yet (OBJ's forward references, a PLY face element before its vertices): decided in Finish.
  first_triangle_.push_back(first);
  corners_.insert(corners_.end(), corners, corners + n);
  if (corner_attributes != nullptr) {
    corner_attributes_.insert(corner_attributes_.end(), corner_attributes, corner_attributes + n);
  }
  corner_start_.push_back(corners_.size());
}

void PolygonSplitter::Replace(const double* xyz, const int* corners, const int* corner_attributes, size_t n,
                              size_t first, std::vector<int>* triangles, std::vector<int>* attributes) {
  if (!EarClip(xyz, corners, n, &clipped_)) return;
  for (size_t k = 0; k < clipped_.size(); ++k) {
    (*triangles)[3 * first + k] = corners[clipped_[k]];
    if (attributes != nullptr) (*attributes)[3 * first + k] = corner_attributes[clipped_[k]];
  }
  ++concave_;
}

void PolygonSplitter::Finish(const Vertices& V, std::vector<int>* triangles, std::vector<int>* attributes,
                             MeshReadSummary* summary) {
  if (count_ == 0) return;
  for (size_t p = 0; p < first_triangle_.size(); ++p) {
    const size_t start = corner_start_[p], n = corner_start_[p + 1] - start;
    const int* corners = corners_.data() + start;
    // Out-of-range corners are the caller's error to report (CheckFaceIndices).
    if (std::any_of(corners, corners + n, [&V](int v) { return v < 0 || v >= V.rows(); })) continue;
    Replace(V.data(), corners, attributes != nullptr ? corner_attributes_.data() + start : nullptr, n,
            first_triangle_[p], triangles, attributes);
  }
  summary->polygons_triangulated = count_;
  summary->notices.push_back(concave_ == 0
                                 ? StrCat(count_, " polygons with more than 3 vertices were fan-triangulated")
                                 : StrCat(count_, " polygons with more than 3 vertices were triangulated (", concave_,
                                          " concave ones by ear clipping in their plane, the others as fans)"));
}

void CheckFaceIndices(const Faces& F, int64_t num_vertices, const char* what) {
  const int* data = F.data();
  const int64_t n = F.size();
  for (int64_t i = 0; i < n; ++i) {
    if (data[i] < 0 || data[i] >= num_vertices) {
      RB_FAIL(what, " ", i / 3, " uses vertex ", data[i], " but there are ", num_vertices, " vertices");
    }
  }
}

}  // namespace mesh_io

namespace {

std::string LowerExtension(const std::string& path) {
  const size_t slash = path.find_last_of('/');
  const size_t dot = path.find_last_of('.');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return {};
  std::string ext = path.substr(dot + 1);
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

struct FileCloser {
  void operator()(FILE* f) const { std::fclose(f); }
};

std::string ReadWholeFile(const std::string& path) {
  std::unique_ptr<FILE, FileCloser> file(std::fopen(path.c_str(), "rb"));
  RB_CHECK(file != nullptr, path, ": cannot open: ", std::strerror(errno));
  struct stat info {};
  RB_CHECK(fstat(fileno(file.get()), &info) == 0, path, ": cannot stat: ", std::strerror(errno));
  RB_CHECK(!S_ISDIR(info.st_mode), path, ": is a directory");
  std::string bytes;
  if (S_ISREG(info.st_mode)) {
    bytes.resize(static_cast<size_t>(info.st_size));
    const size_t got = std::fread(bytes.data(), 1, bytes.size(), file.get());
    RB_CHECK(got == bytes.size(), path, ": read ", got, " of ", bytes.size(), " bytes");
  } else {
    // Pipes and devices have no size: read in chunks.
    char chunk[1 << 16];
    size_t got = 0;
    while ((got = std::fread(chunk, 1, sizeof(chunk), file.get())) > 0) bytes.append(chunk, got);
    RB_CHECK(!std::ferror(file.get()), path, ": read error: ", std::strerror(errno));
  }
  return bytes;
}

// Writers refuse inconsistent meshes rather than produce a file no reader accepts.
void CheckWritable(const NoisyMesh& noisy, const MeshWriteOptions& options, const std::string& path) {
  const Mesh& mesh = noisy.mesh;
  RB_CHECK(options.precision >= 1 && options.precision <= 17, path, ": precision must be in [1, 17], got ",
           options.precision);
  RB_CHECK(mesh.N.rows() == 0 || mesh.N.rows() == mesh.V.rows(), path, ": mesh has ", mesh.N.rows(),
           " normals for ", mesh.V.rows(), " vertices");
  RB_CHECK(noisy.covariance.empty() || noisy.covariance.size() == static_cast<size_t>(mesh.V.rows()), path,
           ": mesh has ", noisy.covariance.size(), " covariances for ", mesh.V.rows(), " vertices");
  RB_CHECK(noisy.pixel.rows() == 0 || noisy.pixel.rows() == mesh.V.rows(), path, ": mesh has ",
           noisy.pixel.rows(), " pixel positions for ", mesh.V.rows(), " vertices");
  try {
    mesh_io::CheckFaceIndices(mesh.F, mesh.V.rows(), "face");
  } catch (const Error& e) {
    RB_FAIL(path, ": cannot write: ", e.what());
  }
  const CornerNormals& corner = options.corner_normals;
  if (!corner.empty()) {
    RB_CHECK(corner.normal_index.rows() == mesh.F.rows(), path, ": corner normals index ",
             corner.normal_index.rows(), " faces but the mesh has ", mesh.F.rows());
    try {
      mesh_io::CheckFaceIndices(corner.normal_index, corner.normals.rows(), "corner normal of face");
    } catch (const Error& e) {
      RB_FAIL(path, ": cannot write: ", e.what());
    }
  }
}

}  // namespace

MeshFormat MeshFormatFromPath(const std::string& path) {
  const std::string ext = LowerExtension(path);
  if (ext == "ply") return MeshFormat::kPly;
  if (ext == "obj") return MeshFormat::kObj;
  if (ext == "off") return MeshFormat::kOff;
  RB_CHECK(!ext.empty(), path, ": no file extension to tell the mesh format (expected .ply, .obj or .off)");
  RB_FAIL(path, ": unknown mesh format '.", ext, "' (expected .ply, .obj or .off)");
}

NoisyMesh ParseNoisyMesh(std::string_view bytes, MeshFormat format, const std::string& name,
                         MeshReadSummary* summary) {
  MeshReadSummary local;
  MeshReadSummary* out = summary != nullptr ? summary : &local;
  *out = MeshReadSummary{};
  out->format = format;
  switch (format) {
    case MeshFormat::kPly:
      return mesh_io::ParsePly(bytes, name, out);
    case MeshFormat::kObj:
      return mesh_io::ParseObj(bytes, name, out);
    case MeshFormat::kOff:
      return mesh_io::ParseOff(bytes, name, out);
  }
  RB_FAIL(name, ": unknown mesh format");
}

NoisyMesh ReadNoisyMesh(const std::string& path, MeshReadSummary* summary) {
  const MeshFormat format = MeshFormatFromPath(path);
  const std::string bytes = ReadWholeFile(path);
  return ParseNoisyMesh(bytes, format, path, summary);
}

RangeGridScan ReadRangeGridScan(const std::string& path, MeshReadSummary* summary) {
  RB_CHECK(MeshFormatFromPath(path) == MeshFormat::kPly, path, ": range grids are read from PLY files only");
  const std::string bytes = ReadWholeFile(path);
  MeshReadSummary local;
  MeshReadSummary* out = summary != nullptr ? summary : &local;
  *out = MeshReadSummary{};
  mesh_io::PlyRangeGrid grid;
  RangeGridScan scan;
  scan.mesh = mesh_io::ParsePly(bytes, path, out, &grid);
  scan.width = grid.width;
  scan.height = grid.height;
  scan.cell_vertex = std::move(grid.cell_vertex);
  return scan;
}

Mesh ReadMesh(const std::string& path, MeshReadSummary* summary) {
  return std::move(ReadNoisyMesh(path, summary).mesh);
}

void WriteMesh(const Mesh& mesh, const std::string& path, const MeshWriteOptions& options) {
  NoisyMesh noisy;
  noisy.mesh = mesh;
  WriteNoisyMesh(noisy, path, options);
}

void WriteNoisyMesh(const NoisyMesh& mesh, const std::string& path, const MeshWriteOptions& options) {
  const MeshFormat format = MeshFormatFromPath(path);
  CheckWritable(mesh, options, path);
  std::string bytes;
  switch (format) {
    case MeshFormat::kPly:
      bytes = mesh_io::FormatPly(mesh, options);
      break;
    case MeshFormat::kObj:
    case MeshFormat::kOff:
      RB_CHECK(mesh.covariance.empty() && mesh.pixel.rows() == 0, path,
               ": only .ply can hold per-vertex covariance and pixel positions");
      bytes = format == MeshFormat::kObj ? mesh_io::FormatObj(mesh.mesh, options)
                                         : mesh_io::FormatOff(mesh.mesh, options);
      break;
  }
  WriteFileAtomically(path, bytes);
}

void WritePolygonMesh(const Vertices& V, const std::vector<std::vector<int>>& polygons, const std::string& path,
                      const MeshWriteOptions& options) {
  const MeshFormat format = MeshFormatFromPath(path);
  RB_CHECK(options.precision >= 1 && options.precision <= 17, path, ": precision must be in [1, 17], got ",
           options.precision);
  for (size_t p = 0; p < polygons.size(); ++p) {
    RB_CHECK(polygons[p].size() >= 3, path, ": polygon ", p, " has ", polygons[p].size(),
             " vertices (at least 3 needed)");
    for (const int v : polygons[p]) {
      RB_CHECK(v >= 0 && v < V.rows(), path, ": polygon ", p, " uses vertex ", v, " but there are ", V.rows(),
               " vertices");
    }
  }
  std::string bytes;
  switch (format) {
    case MeshFormat::kPly:
      bytes = mesh_io::FormatPolygonPly(V, polygons, options);
      break;
    case MeshFormat::kObj:
      bytes = mesh_io::FormatPolygonObj(V, polygons, options);
      break;
    case MeshFormat::kOff:
      bytes = mesh_io::FormatPolygonOff(V, polygons, options);
      break;
  }
  WriteFileAtomically(path, bytes);
}

}  // namespace rangebayes

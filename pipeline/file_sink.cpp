#include "pipeline/file_sink.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <system_error>
#include <vector>

#include "core/error.h"
#include "core/files.h"
#include "core/mesh_io.h"
#include "core/render.h"
#include "pipeline/png.h"
#include "stereo/colormap.h"

namespace rangebayes {
namespace fs = std::filesystem;

namespace {

std::string Name(std::int64_t index, const char* extension) {
  char buffer[40];
  std::snprintf(buffer, sizeof(buffer), "%06lld.%s", static_cast<long long>(index), extension);
  return buffer;
}

void AppendLine(int fd, const std::string& line) {
  const char* p = line.data();
  size_t left = line.size();
  while (left > 0) {
    const ssize_t n = ::write(fd, p, left);
    if (n < 0 && errno == EINTR) continue;
    RB_CHECK(n > 0, "results.csv: write failed (", std::strerror(errno), ")");
    p += n;
    left -= static_cast<size_t>(n);
  }
}

// One view for every panel: the raw mesh as the camera saw it (it is in the rectified left camera's frame),
// fitted to the central 99% of its vertices.
RenderOptions PreviewView(const NoisyMesh& raw, int width, int height) {
  RenderOptions r;
  r.width_px = width;
  r.height_px = height;
  r.margin_fraction = 0.02;
  // (A mesh without pixel coordinates: the same view, fitted to all of it.)
  r.view_direction = Eigen::Vector3d(0, 0, 1);
  r.up = Eigen::Vector3d(0, -1, 0);
  FitView(raw, &r);
  return r;
}

// Whether a results.csv lists a result: a line after its header.
bool ListsAnyResult(const fs::path& index) {
  std::ifstream in(index);
  if (!in) return true;  // unreadable: kept as if it listed results
  std::string line;
  int lines = 0;
  while (lines < 2 && std::getline(in, line)) {
    if (!line.empty()) ++lines;
  }
  return lines >= 2;
}

}  // namespace

void FileSinkOptions::Check() const {
  RB_CHECK(preview_width_px == 0 || (preview_width_px >= 16 && preview_width_px <= 4096),
           "preview width must be 0 or 16..4096 px, got ", preview_width_px);
}

FileSink::FileSink(const std::string& folder, const FileSinkOptions& options) : folder_(folder), options_(options) {
  options_.Check();
  // One run at a time per folder: a second replay into it removed or truncated the first one's results.csv while
  // that run appended to it (both ended "ok", the first run's results unlisted). The lock (on the folder itself)
  // goes with the process, however it ends.
  CreateFolder(folder_);
  lock_fd_ = ::open(folder_.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  RB_CHECK(lock_fd_ >= 0, folder_, ": cannot open (", std::strerror(errno), ")");
  RB_CHECK(::flock(lock_fd_, LOCK_EX | LOCK_NB) == 0, folder_,
           ": another run is writing its results here; wait for it or choose another folder");
  std::error_code ec;
  const fs::path earlier_index = fs::path(folder_) / "results.csv";
  if (fs::exists(earlier_index, ec)) {
    // A results.csv of its header alone (a run that stopped before its first result) holds nothing to keep.
    RB_CHECK(options_.overwrite || !ListsAnyResult(earlier_index), folder_,
             ": holds the results of an earlier run (results.csv); choose another folder, or --overwrite to replace "
             "them");
    // What a run writes here (summary.json by the commands at the end); the console's captures and recordings stay.
    for (const char* name : {"raw", "smoothed", "decimated", "depth", "shaded", "results.csv", "summary.json"}) {
      fs::remove_all(fs::path(folder_) / name, ec);
      RB_CHECK(!ec, folder_, "/", name, ": cannot remove the earlier result (", ec.message(), ")");
    }
  }
  const std::string index = (fs::path(folder_) / "results.csv").string();
  index_fd_ = ::open(index.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_APPEND | O_CLOEXEC, 0644);
  RB_CHECK(index_fd_ >= 0, index, ": cannot create (", std::strerror(errno), ")");
  AppendLine(index_fd_,
             "index,last_index,timestamp_ns,frames,raw_vertices,raw_faces,decimated_faces,raw,smoothed,decimated,"
             "depth,shaded\n");
}

FileSink::~FileSink() {
  Finish();
  if (lock_fd_ >= 0) ::close(lock_fd_);
}

void FileSink::Finish() {
  if (index_fd_ >= 0) {
    ::close(index_fd_);
    index_fd_ = -1;
  }
}

void FileSink::Consume(const PipelineResult& result) {
  const fs::path root(folder_);
  std::string raw, smoothed, decimated, depth, shaded;
  // The frame's files are listed in results.csv only once all are written; when one fails, those written before
  // it are removed, so that no file is left that results.csv does not list.
  std::vector<std::string> written;
  const auto wrote = [&](const std::string& relative) {
    written.push_back(relative);
    ++files_written_;
  };
  // Each output's folder when its first file is written: a run with an output off (or smoothing, decimation off)
  // left an empty folder that the closing line listed as results.
  const auto folder = [&](const char* sub) {
    if (made_.insert(sub).second) CreateFolder((root / sub).string());
  };
  try {
    if (options_.raw_ply) {
      folder("raw");
      raw = "raw/" + Name(result.index, "ply");
      WriteNoisyMesh(result.raw_mesh, (root / raw).string());
      wrote(raw);
    }
    if (options_.smoothed_ply && result.smoothed.has_value()) {
      folder("smoothed");
      smoothed = "smoothed/" + Name(result.index, "ply");
      WriteMesh(*result.smoothed, (root / smoothed).string());
      wrote(smoothed);
    }
    if (options_.decimated_obj && result.decimated.has_value()) {
      folder("decimated");
      decimated = "decimated/" + Name(result.index, "obj");
      MeshWriteOptions w;
      w.corner_normals = result.decimated->corner_normals;
      WriteMesh(result.decimated->mesh, (root / decimated).string(), w);
      wrote(decimated);
    }
    if (options_.depth_png && !result.depth.empty()) {
      folder("depth");
      depth = "depth/" + Name(result.index, "png");
      ColorMapOptions c;
      c.reverse = true;
      WritePng(ColorMap(result.depth.depth_m, c), (root / depth).string());
      wrote(depth);
    }
    if (options_.shaded_png) {
      const int width = options_.preview_width_px > 0 ? options_.preview_width_px : std::max(16, result.depth.width());
      const int height =
          std::max(16, result.depth.width() > 0 ? width * result.depth.height() / result.depth.width() : width * 3 / 4);
      std::vector<RgbImage> panels;
      RenderOptions view = PreviewView(result.raw_mesh, width, height);
      panels.push_back(RenderMesh(result.raw_mesh.mesh, view));
      if (result.smoothed.has_value()) panels.push_back(RenderMesh(*result.smoothed, view));
      if (result.decimated.has_value()) {
        const DecimatedMesh& d = *result.decimated;
        RenderOptions smooth_view = view;
        if (!d.corner_normals.empty()) {
          smooth_view.shading = Shading::kSmooth;
          smooth_view.corner_normals = CornerNormalRows(d.corner_normals);
        }
        panels.push_back(RenderMesh(d.mesh, smooth_view));
      }
      folder("shaded");
      shaded = "shaded/" + Name(result.index, "png");
      WritePng(SideBySide(panels), (root / shaded).string());
      wrote(shaded);
    }
    AppendLine(index_fd_, StrCat(result.index, ',', result.last_index, ',', result.timestamp_ns, ',', result.frames,
                                 ',', result.raw_mesh.mesh.num_vertices(), ',', result.raw_mesh.mesh.num_faces(), ',',
                                 result.decimated.has_value() ? result.decimated->mesh.num_faces() : 0, ',', raw, ',',
                                 smoothed, ',', decimated, ',', depth, ',', shaded, '\n'));
  } catch (...) {
    for (const std::string& relative : written) {
      std::error_code ec;
      fs::remove(root / relative, ec);
      --files_written_;
    }
    throw;
  }
}

}  // namespace rangebayes

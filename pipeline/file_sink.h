// The sink that writes every pipeline result into an output folder:
//   OUT/raw/NNNNNN.ply        triangulated mesh with per-vertex covariance and pixel (core/mesh_io.h)
//   OUT/smoothed/NNNNNN.ply   after Bayesian smoothing
//   OUT/decimated/NNNNNN.obj  after Bayesian decimation, with per-corner shading normals
//   OUT/depth/NNNNNN.png      depth colour-mapped (near warm, no measurement black)
//   OUT/shaded/NNNNNN.png     rendered raw | smoothed | decimated side by side
//   OUT/results.csv           one line per result: indices, timestamp, sizes, file names
// NNNNNN is the frame index (the first frame of a space-time window).
#pragma once

#include <cstdint>
#include <set>
#include <string>

#include "pipeline/pipeline.h"

namespace rangebayes {

struct FileSinkOptions {
  bool raw_ply = true;
  bool smoothed_ply = true;
  bool decimated_obj = true;
  bool depth_png = true;
  bool shaded_png = true;
  int preview_width_px = 0;  // 0: the frame width; else 16–4096, width of each rendered panel
  // A folder that holds an earlier run's results (results.csv) is refused, so that a new run never mixes its
  // frames with the old ones nor replaces them unasked; true: the earlier results are removed first.
  bool overwrite = false;
  void Check() const;
};

class FileSink : public PipelineSink {
 public:
  // Creates the folder; throws Error naming it when it cannot, when another FileSink (of any process) writes into
  // it, or when it holds an earlier run's results and options.overwrite is false. The folder stays locked until
  // this sink is destroyed.
  FileSink(const std::string& folder, const FileSinkOptions& options = {});
  ~FileSink() override;
  FileSink(const FileSink&) = delete;
  FileSink& operator=(const FileSink&) = delete;
  void Consume(const PipelineResult& result) override;
  void Finish() override;
  std::int64_t files_written() const { return files_written_; }

 private:
  std::string folder_;
  FileSinkOptions options_;
  std::int64_t files_written_ = 0;
  int index_fd_ = -1;
  int lock_fd_ = -1;
  std::set<std::string> made_;  // output folders created (each when its first file is written)
};

}  // namespace rangebayes

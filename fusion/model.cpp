#include "fusion/model.h"

#include <Eigen/Geometry>
#include <cstdio>
#include <string_view>
#include <utility>

#include "core/error.h"
#include "core/scan_poses.h"

namespace rangebayes {

void ModelOptions::Check() const {
  registration.Check();
  if (smooth) smoothing.Check();
  fusion.Check();
  if (decimate) decimation.Check();
}

std::vector<Eigen::Isometry3d> PlaceScans(const std::vector<Scan>& scans,
                                          const std::vector<Eigen::Isometry3d>& initial_world_from_scan,
                                          const ModelOptions& options, ModelSummary* summary) {
  options.Check();
  ModelSummary local;
  ModelSummary& out = summary != nullptr ? *summary : local;
  out.registration = {};
  out.pair_report.clear();
  out.notices.clear();
  RB_CHECK(!scans.empty(), "no scans");
  RB_CHECK(initial_world_from_scan.size() == scans.size(), initial_world_from_scan.size(), " initial poses for ",
           scans.size(), " scans");
  RB_CHECK(!options.align || scans.size() >= 2, "alignment needs at least two scans (one scan is fused as it is)");
  if (scans.size() < 2) return initial_world_from_scan;
  if (options.align) {
    RegisterOptions registration = options.registration;
    registration.progress = options.progress;
    std::vector<Eigen::Isometry3d> poses =
        RegisterScans(scans, initial_world_from_scan, registration, &out.registration);
    out.pair_report = FormatPairReport(out.registration, scans);
    return poses;
  }
  const std::string misaligned = CheckPoses(scans, initial_world_from_scan, options.registration, &out.registration);
  out.pair_report = FormatPairReport(out.registration, scans);
  RB_CHECK(misaligned.empty(), misaligned, "; align them first instead of fusing the given poses as they are");
  // Two bunnies 10 cm apart were fused side by side without a word.
  const std::vector<int>& apart = out.registration.apart;
  if (!apart.empty()) {
    std::string names;
    for (const int s : apart) names += (names.empty() ? "" : ", ") + FileBaseName(scans[static_cast<size_t>(s)].name);
    char shares[96];
    std::snprintf(shares, sizeof(shares), "%.1f%% of the samples found a partner, %.1f%% needed to check a pose",
                  100.0 * out.registration.apart_overlap, 100.0 * options.registration.min_overlap);
    out.notices.push_back(StrCat(names, ": the given poses place ", apart.size() == 1 ? "it" : "them",
                                 " apart from every other scan (", shares, "): fused there, unchecked"));
  }
  return initial_world_from_scan;
}

Mesh FuseModel(const std::vector<Scan>& scans, const std::vector<Eigen::Isometry3d>& world_from_scan,
               const ModelOptions& options, ModelSummary* summary) {
  options.Check();
  ModelSummary local;
  ModelSummary& out = summary != nullptr ? *summary : local;
  out.smoothing.clear();
  out.fusion = {};
  out.decimated = false;
  out.decimation = {};
  const auto report = [&](double fraction, const std::string& stage) {
    if (options.progress) options.progress(fraction, stage);
  };

  std::vector<Scan> smoothed;
  if (options.smooth) {
    for (const Scan& scan : scans) {
      SmoothOptions smoothing = options.smoothing;
      const std::string stage = "smoothing " + FileBaseName(scan.name);
      smoothing.progress = [&](double fraction, std::string_view) { report(fraction, stage); };
      SmoothSummary smooth_summary;
      smoothed.push_back(SmoothScan(scan, smoothing, &smooth_summary));
      out.smoothing.push_back(std::move(smooth_summary));
    }
  }
  const NoisyMesh fused = FuseScans(options.smooth ? smoothed : scans, world_from_scan, options.fusion, &out.fusion);
  if (fused.mesh.num_faces() == 0) {
    // A voxel as large as the scans leaves no cell with a zero crossing: the voxel, not the overlap, is then the
    // cause (--voxel 1 on scans a tenth of that across blamed the overlap).
    Eigen::AlignedBox3d box;
    for (size_t i = 0; i < scans.size(); ++i) {
      const Vertices& V = scans[i].noisy.mesh.V;
      for (Eigen::Index v = 0; v < V.rows(); ++v) box.extend(world_from_scan[i] * V.row(v).transpose().eval());
    }
    const double extent = box.isEmpty() ? 0.0 : box.sizes().maxCoeff();
    RB_FAIL("fusion produced no surface (",
            out.fusion.voxel_size > 0.25 * extent ? StrCat("voxel ", out.fusion.voxel_size, " against scans ", extent,
                                                           " across: choose a smaller --voxel")
                                                  : std::string("the scans share no observed voxels"),
            ")");
  }
  if (!options.decimate) return fused.mesh;
  DecimateOptions decimation = options.decimation;
  decimation.progress = [&](double fraction, std::string_view) { report(fraction, "decimation"); };
  DecimatedMesh decimated = Decimate(fused.mesh, decimation, &out.decimation);
  out.decimated = true;
  return std::move(decimated.mesh);
}

}  // namespace rangebayes

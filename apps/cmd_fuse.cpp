// `rangebayes fuse SCAN... [--poses FILE] --out DIR`: align range scans with their covariances and fuse them into
// one mesh, optionally smoothed and decimated by the bayes stages (fusion/model.h).
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "apps/command.h"
#include "apps/flags.h"
#include "apps/progress.h"
#include "core/error.h"
#include "core/files.h"
#include "core/mesh_io.h"
#include "core/render.h"
#include "core/scan_poses.h"
#include "fusion/model.h"
#include "pipeline/png.h"

namespace rangebayes::apps {
namespace {

struct FuseArgs {
  std::vector<std::string> scans;
  std::string poses;
  std::string out_dir;
  bool smooth = false;
  bool decimate = false;
  bool no_align = false;
  double voxel = 0;
  double sigma_range = RangeGridScanOptions{}.sigma_range;
  double sigma_lateral = RangeGridScanOptions{}.sigma_lateral;
  int threads = 0;
  std::vector<double> view{0.0, 0.0, -1.0};
  bool quiet = false;
};

Eigen::Vector3f ScanColour(int k) {
  static const float kColours[][3] = {{0.90f, 0.35f, 0.30f}, {0.30f, 0.60f, 0.90f}, {0.40f, 0.80f, 0.40f},
                                      {0.95f, 0.75f, 0.25f}, {0.70f, 0.45f, 0.85f}, {0.30f, 0.80f, 0.80f},
                                      {0.85f, 0.55f, 0.70f}, {0.60f, 0.60f, 0.35f}, {0.55f, 0.40f, 0.30f},
                                      {0.50f, 0.50f, 0.60f}};
  const float* c = kColours[k % 10];
  return Eigen::Vector3f(c[0], c[1], c[2]);
}

// All scans in the world frame, one colour each.
RgbImage AlignedPicture(const std::vector<Scan>& scans, const std::vector<Eigen::Isometry3d>& poses,
                        const RenderOptions& base) {
  Mesh all;
  int nv = 0, nf = 0;
  for (const Scan& s : scans) {
    nv += s.num_vertices();
    nf += s.noisy.mesh.num_faces();
  }
  all.V.resize(nv, 3);
  all.F.resize(nf, 3);
  RenderOptions options = base;
  options.face_colors.resize(nf, 3);
  int v0 = 0, f0 = 0;
  for (size_t k = 0; k < scans.size(); ++k) {
    const Mesh& m = scans[k].noisy.mesh;
    for (int i = 0; i < m.num_vertices(); ++i) {
      all.V.row(v0 + i) = (poses[k] * Eigen::Vector3d(m.V.row(i))).transpose();
    }
    all.F.middleRows(f0, m.num_faces()) = m.F.array() + v0;
    for (int f = 0; f < m.num_faces(); ++f) options.face_colors.row(f0 + f) = ScanColour(static_cast<int>(k));
    v0 += m.num_vertices();
    f0 += m.num_faces();
  }
  return RenderMesh(all, options);
}

void RunFuse(const FuseArgs& args) {
  // Checked first: an infinite one passed and failed in the renderer after the whole alignment and fusion.
  const Eigen::Vector3d view = ViewDirectionOption(args.view);
  if (args.scans.size() < 2 && !args.no_align) UsageError("fuse needs at least two scans (or --no-align)");
  // Pose files name scans by file name: two scans of one name wrote a poses.conf that fuse then refused.
  for (size_t a = 0; a < args.scans.size(); ++a) {
    for (size_t b = a + 1; b < args.scans.size(); ++b) {
      if (FileBaseName(args.scans[a]) != FileBaseName(args.scans[b])) continue;
      UsageError(StrCat(args.scans[a], " and ", args.scans[b], " have the same file name, by which poses.conf and ",
                        "--poses name scans: rename one (or link it under another name)"));
    }
  }
  RangeGridScanOptions scan_options;
  scan_options.sigma_range = args.sigma_range;
  scan_options.sigma_lateral = args.sigma_lateral;
  scan_options.Check();
  ProgressPrinter progress(args.quiet);
  ModelOptions options;
  options.align = !args.no_align;
  options.registration.num_threads = args.threads;
  options.smooth = args.smooth;
  options.smoothing.num_threads = args.threads;
  options.fusion.voxel_size = args.voxel;
  options.decimate = args.decimate;
  options.progress = progress.callback();
  options.Check();

  std::vector<ScanPose> file_poses;
  if (!args.poses.empty()) file_poses = ReadScanPoses(args.poses);
  std::vector<Scan> scans;
  std::vector<Eigen::Isometry3d> initial;
  for (const std::string& path : args.scans) {
    RangeGridScanSummary grid;
    scans.push_back(ReadScan(path, scan_options, &grid));
    const Scan& s = scans.back();
    std::printf("scan:       %s: %d vertices, %d faces, mean edge %.4g%s\n", path.c_str(), s.num_vertices(),
                s.noisy.mesh.num_faces(), s.mean_edge,
                grid.ray_model.empty() ? " (mesh)" : (" (range grid, rays: " + grid.ray_model + ")").c_str());
    initial.push_back(file_poses.empty() ? Eigen::Isometry3d::Identity()
                                         : FindScanPose(file_poses, path, args.poses).world_from_scan);
  }
  CreateFolder(args.out_dir);
  const std::string dir = args.out_dir + "/";

  // The pair report is written also when the given poses fail their check: it says which pairs disagree.
  ModelSummary summary;
  const auto write_report = [&] {
    if (summary.pair_report.empty()) return;
    WriteFileAtomically(dir + "report.txt", summary.pair_report);
    std::printf("%s", summary.pair_report.c_str());
    std::printf("report:     %sreport.txt\n", dir.c_str());
  };
  std::vector<Eigen::Isometry3d> poses;
  try {
    poses = PlaceScans(scans, initial, options, &summary);
  } catch (const Error&) {
    write_report();
    throw;
  }
  if (options.align) std::printf("alignment:  %s\n", summary.registration.BriefReport().c_str());
  write_report();
  for (const std::string& notice : summary.notices) Notice(args.quiet, notice);
  std::vector<ScanPose> out_poses;
  for (size_t k = 0; k < scans.size(); ++k) out_poses.push_back({FileBaseName(scans[k].name), poses[k]});
  WriteScanPoses(out_poses, dir + "poses.conf");
  std::printf("poses:      %sposes.conf (first scan fixed)\n", dir.c_str());

  const Mesh model = FuseModel(scans, poses, options, &summary);
  progress.Finish();
  for (size_t k = 0; k < summary.smoothing.size(); ++k) {
    std::printf("smoothing:  %s\n%s", FileBaseName(scans[k].name).c_str(), summary.smoothing[k].BriefReport().c_str());
  }
  std::printf("fusion:     %s\n", summary.fusion.BriefReport().c_str());
  if (summary.decimated) std::printf("decimation:\n%s", summary.decimation.BriefReport().c_str());
  WriteMesh(model, dir + "fused.ply");
  std::printf("model:      %sfused.ply (%d vertices, %d faces)\n", dir.c_str(), model.num_vertices(),
              model.num_faces());

  RenderOptions render;
  render.view_direction = view;
  render.width_px = 640;
  render.height_px = 640;
  WritePng(AlignedPicture(scans, poses, render), dir + "aligned.png");
  render.shading = Shading::kSmooth;
  WritePng(RenderMesh(model, render), dir + "fused.png");
  std::printf("pictures:   %saligned.png (one colour per scan), %sfused.png\n", dir.c_str(), dir.c_str());
}

}  // namespace

RB_REGISTER_COMMANDS(35, [](CLI::App& app) {
  auto args = std::make_shared<FuseArgs>();
  auto* sub = app.add_subcommand("fuse",
                                 "Align range scans with their covariances (multi-scan GICP) and fuse them into one "
                                 "mesh (TSDF weighted by 1/sigma_ray^2, marching cubes)");
  sub->add_option("SCAN", args->scans,
                  "Scans: PLY range grids (Stanford/Cyberware 'range_grid'), or meshes such as 'replay' writes "
                  "(PLY with covariances; plain meshes get the generic noise model)")
      ->required()
      ->check(CLI::ExistingFile);
  sub->add_option("--poses", args->poses,
                  "Initial poses, bun.conf format 'bmesh FILE tx ty tz qx qy qz qw' (default: identity, i.e. "
                  "the scans are taken as roughly pre-aligned)");
  sub->add_option("--out,-o", args->out_dir, "Output folder: poses.conf, fused.ply, report.txt, aligned.png, fused.png")
      ->required();
  sub->add_flag("--smooth", args->smooth,
               "Bayesian smoothing (bayes/smooth.h defaults) of each scan with its own ray covariance, after "
               "alignment and before fusion");
  sub->add_flag("--decimate", args->decimate, "Bayesian decimation of the (smoothed) fused mesh (defaults)");
  sub->add_flag("--no-align", args->no_align,
                "Fuse with the given poses as they are (after the test registration's result passes: scans they "
                "leave misaligned are an error; report.txt is written either way)");
  sub->add_option("--voxel", args->voxel, "Voxel size in model units (default: the scans' mean edge length)")
      ->check(NonNegativeReal());
  sub->add_option("--sigma-range", args->sigma_range, "Range-grid scans: noise along the ray, model units (> 0)")
      ->check(PositiveReal());
  sub->add_option("--sigma-lateral", args->sigma_lateral, "Range-grid scans: noise across the ray, model units (> 0)")
      ->check(PositiveReal());
  AddThreadsOption(sub, &args->threads);
  sub->add_option("--view", args->view, "View direction x y z of the pictures (world frame)")->expected(3);
  AddQuietFlag(sub, &args->quiet);
  sub->callback([args] { RunFuse(*args); });
});

}  // namespace rangebayes::apps

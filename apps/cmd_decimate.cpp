// `rangebayes decimate`: Bayesian decimation of a mesh (or of the poses of an animated mesh) into planar patches.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "apps/command.h"
#include "apps/flags.h"
#include "apps/progress.h"
#include "apps/read_input.h"
#include "bayes/decimation/decimate.h"
#include "core/error.h"
#include "core/files.h"
#include "core/mesh_io.h"
#include "core/render.h"
#include "pipeline/png.h"

namespace rangebayes::apps {
namespace {

struct DecimateArgs {
  std::vector<std::string> files;
  std::string out_dir;
  double lambda = DecimateOptions{}.lambda;
  int target_faces = 0;
  double chain_tolerance = DecimateOptions{}.chain_tolerance_rel;
  double chain_reserve = DecimateOptions{}.chain_reserve_share;
  bool uniform = false;
  bool polygons = false;
  bool no_refit = false;
  std::string png;
  bool quiet = false;
};

// Distinct, stable colours for patch ids (golden-ratio hue steps).
Eigen::Vector3f PatchColour(int k) {
  const double h = std::fmod(0.13 + 0.618033988749895 * k, 1.0) * 6.0;
  const double s = 0.55 + 0.3 * ((k * 7) % 3) / 2.0, v = 0.95;
  const int i = static_cast<int>(h);
  const double f = h - i, p = v * (1 - s), q = v * (1 - s * f), t = v * (1 - s * (1 - f));
  double r = v, g = t, b = p;
  switch (i % 6) {
    case 1: r = q; g = v; b = p; break;
    case 2: r = p; g = v; b = t; break;
    case 3: r = p; g = q; b = v; break;
    case 4: r = t; g = p; b = v; break;
    case 5: r = v; g = p; b = q; break;
    default: break;
  }
  return Eigen::Vector3f(static_cast<float>(r), static_cast<float>(g), static_cast<float>(b));
}

// Dense mesh | dense faces coloured by patch | decimated mesh with its patch normal fields, in one framing
// fitted to the dense mesh: a depth image's mesh as its camera saw it, any other from an oblique view.
RgbImage Picture(const NoisyMesh& input, const DecimatedMesh& d) {
  const Mesh& dense = input.mesh;
  RenderOptions options;
  options.width_px = 640;
  options.height_px = 520;
  options.view_direction = Eigen::Vector3d(-0.6, -0.5, -1.0);
  FitView(input, &options);
  const RgbImage a = RenderMesh(dense, options);
  RenderOptions coloured = options;
  coloured.face_colors.resize(dense.num_faces(), 3);
  for (int f = 0; f < dense.num_faces(); ++f) {
    const int k = d.dense_face_patch[f];
    coloured.face_colors.row(f) = k < 0 ? Eigen::Vector3f(0.2f, 0.2f, 0.2f).transpose() : PatchColour(k).transpose();
  }
  const RgbImage b = RenderMesh(dense, coloured);
  RenderOptions smooth = options;
  smooth.shading = Shading::kSmooth;
  smooth.corner_normals = CornerNormalRows(d.corner_normals);
  const RgbImage c = RenderMesh(d.mesh, smooth);
  return SideBySide({a, b, c});
}

void WriteOne(const DecimatedMesh& d, const std::string& path, bool polygons) {
  if (polygons) {
    WritePolygonMesh(d.mesh.V, d.polygons, path);
    return;
  }
  MeshWriteOptions options;
  if (MeshFormatFromPath(path) != MeshFormat::kOff) options.corner_normals = d.corner_normals;
  WriteMesh(d.mesh, path, options);
}

void Run(const DecimateArgs& a) {
  const bool animated = !a.out_dir.empty();
  if (!animated && a.files.size() != 2) {
    UsageError("give IN OUT, or several poses with --out DIR (got " + std::to_string(a.files.size()) + " files)");
  }
  if (animated && a.files.empty()) UsageError("--out DIR needs at least one pose");
  std::vector<std::string> inputs = a.files;
  if (!animated) inputs.resize(1);
  // Animated: one OBJ per pose, named after it. Two poses with one name (a/pose.ply and b/pose.obj) would write
  // one file twice, and a pose in the output folder would be overwritten by its own result: refused before any
  // work.
  std::vector<std::string> outputs;
  if (animated) {
    namespace fs = std::filesystem;
    for (size_t m = 0; m < inputs.size(); ++m) {
      const fs::path out = fs::path(a.out_dir) / (fs::path(inputs[m]).stem().string() + ".obj");
      for (size_t k = 0; k < m; ++k) {
        if (outputs[k] == out.string()) {
          UsageError("poses " + inputs[k] + " and " + inputs[m] + " would both be written to " + out.string() +
                     " (one file per pose name)");
        }
      }
      std::error_code error;
      if (fs::equivalent(out, inputs[m], error)) {
        UsageError(inputs[m] + " would be overwritten by its own result: choose another --out folder");
      }
      outputs.push_back(out.string());
    }
  }

  DecimateOptions options;
  options.lambda = a.lambda;
  options.target_faces = a.target_faces;
  options.chain_tolerance_rel = a.chain_tolerance;
  options.chain_reserve_share = a.chain_reserve;
  options.weighting = a.uniform ? DecimateWeighting::kUniform : DecimateWeighting::kArea;
  options.refit_vertices = !a.no_refit;
  options.Check();

  if (animated) {
    CreateFolder(a.out_dir);
    std::vector<std::pair<std::string, std::string>> written;
    for (const std::string& out : outputs) {
      CheckFileToWrite(out);
      written.emplace_back("an output pose", out);
    }
    written.emplace_back("--png", a.png);
    RequireDistinctOutputs(written);
  } else {
    // As for a pose in animated mode: the input replaced by its own result is refused before any work.
    std::error_code error;
    if (std::filesystem::equivalent(a.files[1], a.files[0], error)) {
      UsageError(a.files[0] + " would be overwritten by its own result: give another OUT");
    }
    CheckOutputMesh(a.files[1]);
    RequireDistinctOutputs({{"OUT", a.files[1]}, {"--png", a.png}});
  }
  if (!a.png.empty()) CheckFileToWrite(a.png);

  std::vector<Mesh> poses;
  NoisyMesh first;  // the first pose's pixel coordinates, for the picture (its mesh stays in poses)
  for (const std::string& path : inputs) {
    NoisyMesh input = ReadInputMesh(path, a.quiet);
    if (poses.empty()) first.pixel = std::move(input.pixel);
    poses.push_back(std::move(input.mesh));
    const std::string difference = ConnectivityDifference(poses[0], poses.back());
    RB_CHECK(difference.empty(), "decimate: ", path, " does not have the connectivity of ", inputs[0], ": ",
             difference);
  }
  DecimateSummary s;
  std::vector<DecimatedMesh> out;
  {
    ProgressPrinter progress(a.quiet);
    options.progress = progress.callback();
    out = DecimateAnimated(poses, options, &s);
    progress.Finish();
  }
  for (const std::string& n : s.notices) Notice(a.quiet, n);

  std::vector<std::string> written;
  if (animated) {
    for (size_t m = 0; m < out.size(); ++m) {
      WriteOne(out[m], outputs[m], a.polygons);
      written.push_back(outputs[m]);
    }
  } else {
    WriteOne(out[0], a.files[1], a.polygons);
    written.push_back(a.files[1]);
  }
  if (!a.png.empty()) {
    first.mesh = poses[0];
    WritePng(Picture(first, out[0]), a.png);
    written.push_back(a.png);
  }

  std::fputs(s.BriefReport().c_str(), stdout);
  if (a.polygons) {
    // What the file holds ("output: N faces" counts triangles): one polygon per patch, the triangles of a patch
    // that is not a disk.
    const std::vector<std::vector<int>>& polygons = out[0].polygons;
    const auto triangles = std::count_if(polygons.begin(), polygons.end(), [](const auto& p) { return p.size() == 3; });
    std::printf(
        "written as one polygon per patch: %zu polygons, %lld of them triangles (a patch that is not a disk "
        "is written as its triangles)\n",
        polygons.size(), static_cast<long long>(triangles));
  }
  for (const std::string& w : written) std::printf("wrote %s\n", w.c_str());
}

}  // namespace

RB_REGISTER_COMMANDS(40, [](CLI::App& app) {
  auto a = std::make_shared<DecimateArgs>();
  CLI::App* sub = app.add_subcommand(
      "decimate",
      "Bayesian decimation into planar patches with smooth per-patch shading normals (paper section 6).\n"
      "  rangebayes decimate IN OUT [--lambda L | --target-faces N] [--png FILE] [--polygons]\n"
      "  rangebayes decimate POSE1 POSE2 ... --out DIR   (animated: one patch map shared by all poses)");
  sub->add_option("FILES", a->files, "IN OUT (PLY/OBJ/OFF), or the poses of one connectivity with --out")->required();
  sub->add_option("--out,-o", a->out_dir, "Animated mode: write one decimated OBJ per pose into this folder");
  auto* lambda = sub->add_option("--lambda", a->lambda,
                                 "Energy cost of one patch (normal difference squared x faces, area weights "
                                 "normalised to mean 1): larger gives fewer patches")
                     ->check(PositiveReal());
  auto* target_faces =
      sub->add_option("--target-faces", a->target_faces,
                      "Find lambda by a search for this many output triangles (normally the output has N or N-1; "
                      "more when N is below what one patch per component needs, with a notice)")
          ->check(PositiveInteger())
          ->excludes(lambda);
  sub->add_option("--chain-tolerance", a->chain_tolerance,
                  "Patch-boundary chains are straightened while removed vertices stay within this share of the "
                  "bounding-box diagonal (with --target-faces the budget decides instead)")
      ->check(NonNegativeReal());
  sub->add_option("--chain-reserve", a->chain_reserve,
                  "With --target-faces: share of the triangle budget kept for patch-boundary detail, in [0, 0.99]")
      ->check(RealRange(0.0, 0.99))
      ->needs(target_faces);  // without a budget there is nothing to reserve (it was accepted and did nothing)
  sub->add_flag("--uniform-weights", a->uniform, "Weight every face 1 (the paper) instead of by its area");
  sub->add_flag("--no-refit", a->no_refit,
                "Keep the kept vertices where they are in the input (no refit of their positions, no edge flips)");
  sub->add_flag("--polygons", a->polygons, "Write one polygon per patch instead of triangles (no normals)");
  sub->add_option("--png", a->png, "Picture: dense mesh | patches in colours | decimated mesh, smooth-shaded");
  AddQuietFlag(sub, &a->quiet);
  sub->callback([a] { Run(*a); });
});

}  // namespace rangebayes::apps

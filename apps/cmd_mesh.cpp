// `rangebayes info MESH` and `rangebayes convert IN OUT`.
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "apps/command.h"
#include "apps/flags.h"
#include "apps/progress.h"
#include "core/error.h"
#include "core/mesh_io.h"
#include "core/topology.h"
#include "core/validate.h"

namespace rangebayes::apps {
namespace {

const char* FormatName(MeshFormat format) {
  switch (format) {
    case MeshFormat::kPly:
      return "ply";
    case MeshFormat::kObj:
      return "obj";
    case MeshFormat::kOff:
      return "off";
  }
  return "?";
}

struct InfoArgs {
  std::string mesh_path;
  bool json = false;
};

struct BoundingBox {
  Eigen::RowVector3d min = Eigen::RowVector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::RowVector3d max = Eigen::RowVector3d::Constant(-std::numeric_limits<double>::infinity());
  bool empty() const { return !(min.array() <= max.array()).all(); }
};

// Over finite vertices only: one NaN must not hide the extent of the rest.
BoundingBox FiniteBoundingBox(const Vertices& V) {
  BoundingBox box;
  for (Eigen::Index i = 0; i < V.rows(); ++i) {
    if (!V.row(i).allFinite()) continue;
    box.min = box.min.cwiseMin(V.row(i));
    box.max = box.max.cwiseMax(V.row(i));
  }
  return box;
}

nlohmann::json Vec(const Eigen::RowVector3d& v) { return nlohmann::json::array({v(0), v(1), v(2)}); }

void RunInfo(const InfoArgs& args) {
  MeshReadSummary summary;
  const NoisyMesh noisy = ReadNoisyMesh(args.mesh_path, &summary);
  const Mesh& mesh = noisy.mesh;
  const MeshValidation validation = ValidateMesh(mesh);
  const EdgeTopology topology = ComputeEdgeTopology(mesh);  // the readers reject out-of-range indices
  const double mean_edge = MeanEdgeLength(mesh, topology);
  const Components components = ComputeComponents(mesh);
  const auto loops = ComputeBoundaryLoops(mesh, topology);
  const BoundingBox box = FiniteBoundingBox(mesh.V);

  if (args.json) {
    nlohmann::json out;
    out["file"] = args.mesh_path;
    out["format"] = FormatName(summary.format);
    out["vertices"] = mesh.num_vertices();
    out["faces"] = mesh.num_faces();
    out["edges"] = topology.edges.rows();
    out["has_normals"] = mesh.N.rows() > 0;
    out["has_covariance"] = noisy.has_covariance();
    out["has_pixels"] = noisy.pixel.rows() > 0;
    if (box.empty()) {
      out["bounding_box"] = nullptr;
    } else {
      out["bounding_box"] = {{"min", Vec(box.min)}, {"max", Vec(box.max)}, {"size", Vec(box.max - box.min)}};
    }
    out["mean_edge_length"] = std::isfinite(mean_edge) ? nlohmann::json(mean_edge) : nlohmann::json(nullptr);
    out["components"] = components.count;
    out["boundary_loops"] = loops.size();
    out["polygons_triangulated"] = summary.polygons_triangulated;
    out["validation"] = {{"clean", validation.clean()},
                         {"out_of_range_indices", validation.out_of_range_indices},
                         {"degenerate_faces", validation.degenerate_faces},
                         {"zero_area_faces", validation.zero_area_faces},
                         {"duplicate_faces", validation.duplicate_faces},
                         {"non_finite_vertices", validation.non_finite_vertices},
                         {"unreferenced_vertices", validation.unreferenced_vertices},
                         {"non_manifold_edges", validation.non_manifold_edges},
                         {"non_manifold_vertices", validation.non_manifold_vertices},
                         {"inconsistent_edges", validation.inconsistent_edges},
                         {"boundary_edges", validation.boundary_edges}};
    out["notices"] = summary.notices;
    std::printf("%s\n", out.dump(2).c_str());
    return;
  }
  std::printf("file:             %s (%s)\n", args.mesh_path.c_str(), FormatName(summary.format));
  std::printf("vertices:         %d\n", mesh.num_vertices());
  std::printf("faces:            %d\n", mesh.num_faces());
  std::printf("edges:            %lld (%lld on the boundary)\n", static_cast<long long>(topology.edges.rows()),
              static_cast<long long>(validation.boundary_edges));
  std::printf("per-vertex data:  normals %s, covariance %s, pixels %s\n", mesh.N.rows() > 0 ? "yes" : "no",
              noisy.has_covariance() ? "yes" : "no", noisy.pixel.rows() > 0 ? "yes" : "no");
  if (box.empty()) {
    std::printf("bounding box:     none (no finite vertices)\n");
  } else {
    std::printf("bounding box:     min (%.6g, %.6g, %.6g) max (%.6g, %.6g, %.6g)\n", box.min(0), box.min(1),
                box.min(2), box.max(0), box.max(1), box.max(2));
    const Eigen::RowVector3d size = box.max - box.min;
    std::printf("                  size (%.6g, %.6g, %.6g)\n", size(0), size(1), size(2));
  }
  std::printf("mean edge length: %.6g\n", mean_edge);
  std::printf("components:       %d\n", components.count);
  std::printf("boundary loops:   %zu\n", loops.size());
  const auto findings = DescribeFindings(validation);
  if (findings.empty()) {
    std::printf("validation:       clean\n");
  } else {
    std::printf("validation:       %zu kinds of defect\n", findings.size());
    for (const std::string& line : findings) std::printf("  %s\n", line.c_str());
  }
  for (const std::string& notice : summary.notices) std::printf("note: %s\n", notice.c_str());
}

struct ConvertArgs {
  std::string in_path;
  std::string out_path;
  bool ascii = false;
  bool big_endian = false;
  bool quiet = false;
};

void RunConvert(const ConvertArgs& args) {
  if (args.ascii && args.big_endian) UsageError("--ascii and --big-endian exclude each other");
  const MeshFormat out_format = MeshFormatFromPath(args.out_path);
  if ((args.ascii || args.big_endian) && out_format != MeshFormat::kPly) {
    UsageError("--ascii and --big-endian apply to .ply output only");
  }
  MeshReadSummary summary;
  NoisyMesh noisy = ReadNoisyMesh(args.in_path, &summary);
  for (const std::string& notice : summary.notices) Notice(args.quiet, args.in_path + ": " + notice);
  MeshWriteOptions options;
  if (args.ascii) options.ply_encoding = PlyEncoding::kAscii;
  if (args.big_endian) options.ply_encoding = PlyEncoding::kBinaryBigEndian;
  if (out_format != MeshFormat::kPly && (noisy.has_covariance() || noisy.pixel.rows() > 0)) {
    Notice(args.quiet, "dropping per-vertex covariance and pixel positions: only .ply can hold them");
    noisy.covariance.clear();
    noisy.pixel.resize(0, 2);
  }
  WriteNoisyMesh(noisy, args.out_path, options);
  Notice(args.quiet, StrCat("wrote ", args.out_path, ": ", noisy.mesh.num_vertices(), " vertices, ",
                            noisy.mesh.num_faces(), " faces"));
}

void AddCommands(CLI::App& app) {
  {
    auto args = std::make_shared<InfoArgs>();
    auto* sub = app.add_subcommand("info", "Print counts, bounding box, mean edge length, components, "
                                           "boundary loops and validation findings of a mesh (.ply/.obj/.off)");
    sub->add_option("MESH", args->mesh_path, "mesh file to describe (.ply, .obj or .off)")->required();
    sub->add_flag("--json", args->json, "print one JSON object instead of text");
    sub->callback([args] { RunInfo(*args); });
  }
  {
    auto args = std::make_shared<ConvertArgs>();
    auto* sub = app.add_subcommand("convert", "Convert a mesh between PLY, OBJ and OFF (format from the "
                                              "extensions); vertex order and faces are kept exactly");
    sub->add_option("IN", args->in_path, "input mesh (.ply, .obj or .off)")->required();
    sub->add_option("OUT", args->out_path, "output mesh (.ply, .obj or .off); PLY is binary little endian "
                                           "unless --ascii or --big-endian")
        ->required();
    sub->add_flag("--ascii", args->ascii, "write ascii PLY (17 significant digits, exact)");
    sub->add_flag("--big-endian", args->big_endian, "write binary big-endian PLY");
    AddQuietFlag(sub, &args->quiet);
    sub->callback([args] { RunConvert(*args); });
  }
}

}  // namespace

RB_REGISTER_COMMANDS(10, AddCommands);

}  // namespace rangebayes::apps

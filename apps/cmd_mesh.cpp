// `rangebayes info MESH` and `rangebayes convert IN OUT`.
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "apps/command.h"
#include "apps/flags.h"
#include "apps/progress.h"
#include "apps/read_input.h"
#include "core/error.h"
#include "core/json_text.h"
#include "core/mesh_info.h"
#include "core/mesh_io.h"
#include "fusion/scan.h"

namespace rangebayes::apps {
namespace {

struct InfoArgs {
  std::string mesh_path;
  bool json = false;
};

nlohmann::json Vec(const Eigen::RowVector3d& v) { return nlohmann::json::array({v(0), v(1), v(2)}); }

void RunInfo(const InfoArgs& args) {
  MeshReadSummary summary;
  const NoisyMesh noisy = ReadMeshOrRangeGrid(args.mesh_path, &summary);
  if (!summary.range_grid.empty()) summary.notices.push_back(summary.range_grid);  // info lists it as a note
  const MeshInfo info = DescribeMesh(noisy);
  if (args.json) {
    const MeshValidation& v = info.validation;
    nlohmann::json out;
    out["file"] = args.mesh_path;
    out["format"] = MeshFormatName(summary.format);
    out["vertices"] = info.vertices;
    out["faces"] = info.faces;
    out["edges"] = info.edges;
    out["has_normals"] = info.has_normals;
    out["has_covariance"] = info.has_covariance;
    out["has_pixels"] = info.has_pixels;
    if (!info.has_bounding_box) {
      out["bounding_box"] = nullptr;
    } else {
      out["bounding_box"] = {
          {"min", Vec(info.box_min)}, {"max", Vec(info.box_max)}, {"size", Vec(info.box_max - info.box_min)}};
    }
    out["mean_edge_length"] =
        std::isfinite(info.mean_edge_length) ? nlohmann::json(info.mean_edge_length) : nlohmann::json(nullptr);
    out["components"] = info.components;
    out["boundary_loops"] = info.boundary_loops;
    out["polygons_triangulated"] = summary.polygons_triangulated;
    out["validation"] = {{"clean", v.clean()},
                         {"out_of_range_indices", v.out_of_range_indices},
                         {"degenerate_faces", v.degenerate_faces},
                         {"zero_area_faces", v.zero_area_faces},
                         {"duplicate_faces", v.duplicate_faces},
                         {"non_finite_vertices", v.non_finite_vertices},
                         {"out_of_scale_vertices", v.out_of_scale_vertices},
                         {"below_scale_extent", v.below_scale_extent},
                         {"unreferenced_vertices", v.unreferenced_vertices},
                         {"non_manifold_edges", v.non_manifold_edges},
                         {"non_manifold_vertices", v.non_manifold_vertices},
                         {"inconsistent_edges", v.inconsistent_edges},
                         {"boundary_edges", v.boundary_edges}};
    out["notices"] = summary.notices;
    std::printf("%s\n", JsonText(out, 2).c_str());
    return;
  }
  std::printf("file:             %s (%s)\n%s", args.mesh_path.c_str(), MeshFormatName(summary.format),
              info.BriefReport().c_str());
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
  NoisyMesh noisy = ReadInputMesh(args.in_path, args.quiet);
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
    sub->add_option("MESH", args->mesh_path, "Mesh file to describe (.ply, .obj or .off)")->required();
    sub->add_flag("--json", args->json, "Print one JSON object instead of text");
    sub->callback([args] { RunInfo(*args); });
  }
  {
    auto args = std::make_shared<ConvertArgs>();
    auto* sub = app.add_subcommand("convert", "Convert a mesh between PLY, OBJ and OFF (format from the "
                                              "extensions); vertex order and faces are kept exactly");
    sub->add_option("IN", args->in_path, "Input mesh (.ply, .obj or .off)")->required();
    sub->add_option("OUT", args->out_path,
                    "Output mesh (.ply, .obj or .off); PLY is binary little endian "
                    "unless --ascii or --big-endian")
        ->required();
    sub->add_flag("--ascii", args->ascii, "Write ascii PLY (17 significant digits, exact)");
    sub->add_flag("--big-endian", args->big_endian, "Write binary big-endian PLY");
    AddQuietFlag(sub, &args->quiet);
    sub->callback([args] { RunConvert(*args); });
  }
}

}  // namespace

RB_REGISTER_COMMANDS(10, AddCommands);

}  // namespace rangebayes::apps

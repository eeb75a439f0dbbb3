// fusion/: many scans to one model (what `rangebayes fuse` does, without its files and pictures).
#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "core/scan_poses.h"
#include "python/src/bindings.h"
#include "python/src/convert.h"
#include "python/src/option_tables.h"

namespace rangebayes::python {
namespace {

// A rigid 4×4 world_from_scan matrix (rotation orthonormal within 1e-6, det +1, last row 0 0 0 1).
Eigen::Isometry3d PoseFromArray(py::handle value, size_t k) {
  const std::string what = "fuse: poses[" + std::to_string(k) + "]";
  py::array_t<double, py::array::c_style | py::array::forcecast> a;
  try {
    a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(value);
  } catch (const py::error_already_set&) {
  }
  if (!a || a.ndim() != 2 || a.shape(0) != 4 || a.shape(1) != 4)
    throw py::value_error(what + ": expected a 4x4 matrix");
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) {
      m(r, c) = a.at(r, c);
      if (!std::isfinite(m(r, c))) throw py::value_error(what + ": not finite");
    }
  }
  const Eigen::Matrix3d rotation = m.topLeftCorner<3, 3>();
  if (!(m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).isZero(1e-12) ||
      !(rotation.transpose() * rotation - Eigen::Matrix3d::Identity()).isZero(1e-6) || rotation.determinant() < 0) {
    throw py::value_error(what + ": not a rigid motion (rotation and translation, last row 0 0 0 1)");
  }
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = rotation;
  pose.translation() = m.topRightCorner<3, 1>();
  return pose;
}

py::array PosesToArray(const std::vector<Eigen::Isometry3d>& poses) {
  py::array_t<double> out({static_cast<py::ssize_t>(poses.size()), py::ssize_t{4}, py::ssize_t{4}});
  auto view = out.mutable_unchecked<3>();
  for (size_t k = 0; k < poses.size(); ++k) {
    const Eigen::Matrix4d m = poses[k].matrix();
    for (int r = 0; r < 4; ++r) {
      for (int c = 0; c < 4; ++c) view(static_cast<py::ssize_t>(k), r, c) = m(r, c);
    }
  }
  return out;
}

}  // namespace

void BindFusion(py::module_& m) {
  py::class_<RegisterSummary>(m, "RegisterSummary",
                              "What the alignment (or the check of given poses) found; brief_report() is the line "
                              "`rangebayes fuse` prints.")
      .def_readonly("iterations", &RegisterSummary::iterations)
      .def_readonly("levels", &RegisterSummary::levels)
      .def_readonly("time_s", &RegisterSummary::time_s)
      .def_property_readonly(
          "pairs",
          [](const RegisterSummary& s) {
            py::list out;
            for (const PairReport& p : s.pairs) {
              py::dict d;
              d["a"] = p.a;
              d["b"] = p.b;
              d["samples"] = p.samples;
              d["correspondences"] = p.correspondences;
              d["overlap"] = p.overlap;
              d["rms_sigma"] = p.rms_sigma;
              d["rms_distance"] = p.rms_distance;
              out.append(d);
            }
            return out;
          },
          "per ordered pair of scans (indices a, b): samples, correspondences, overlap, rms_sigma, rms_distance")
      .def("brief_report", &RegisterSummary::BriefReport);
  py::class_<FuseSummary>(m, "FuseSummary", "The volumetric fusion: voxel grid, measurements, the mesh made.")
      .def_readonly("voxel_size", &FuseSummary::voxel_size)
      .def_property_readonly("grid",
                             [](const FuseSummary& s) { return py::make_tuple(s.grid.x(), s.grid.y(), s.grid.z()); })
      .def_readonly("observed_voxels", &FuseSummary::observed_voxels)
      .def_readonly("measurements", &FuseSummary::measurements)
      .def_readonly("vertices", &FuseSummary::vertices)
      .def_readonly("faces", &FuseSummary::faces)
      .def_readonly("boundary_edges", &FuseSummary::boundary_edges)
      .def_readonly("time_s", &FuseSummary::time_s)
      .def("brief_report", &FuseSummary::BriefReport);
  py::class_<ModelSummary>(m, "ModelSummary", "What fuse() did, step by step.")
      .def_readonly("registration", &ModelSummary::registration, "RegisterSummary (empty for one scan)")
      .def_readonly("pair_report", &ModelSummary::pair_report, "the per-pair table `fuse` writes to report.txt")
      .def_readonly("smoothing", &ModelSummary::smoothing, "one SmoothSummary per scan when smooth=True")
      .def_readonly("fusion", &ModelSummary::fusion)
      .def_property_readonly(
          "decimation",
          [](const ModelSummary& s) { return s.decimated ? py::cast(s.decimation) : py::object(py::none()); },
          "DecimateSummary when decimate=True, else None")
      .def_readonly("notices", &ModelSummary::notices,
                    "what fuse() also raised as UserWarnings (scans the given poses place apart from every other)");

  m.def(
      "fuse",
      [](py::handle scan_args, py::object poses_arg, py::kwargs kwargs) {
        py::dict kw = py::dict(kwargs);
        ModelOptions options;
        options.progress = PythonProgress(PopKeyword(kw, "progress"));
        RangeGridScanOptions scan_options;
        ApplyNestedKeywords(kw, "scan", ScanOptionFields(), &scan_options, "fuse");
        ApplyNestedKeywords(kw, "registration", RegisterOptionFields(), &options.registration, "fuse");
        ApplyNestedKeywords(kw, "smoothing", SmoothOptionFields(), &options.smoothing, "fuse");
        ApplyNestedKeywords(kw, "fusion", FuseOptionFields(), &options.fusion, "fuse");
        ApplyNestedKeywords(kw, "decimation", DecimateOptionFields(), &options.decimation, "fuse");
        ApplyKeywords(ModelOptionFields(), kw, &options, "fuse",
                      "progress, scan, registration, smoothing, fusion, decimation");
        scan_options.Check();
        options.Check();
        if (py::isinstance<py::str>(scan_args) || IsPathLike(scan_args) || !py::isinstance<py::iterable>(scan_args)) {
          throw py::type_error("fuse: scans must be a list of paths or meshes");
        }

        // Scans: file paths (read as `fuse` reads them) or meshes (Mesh: the generic noise model; NoisyMesh:
        // its covariances, rays as MakeScanFromMesh finds them).
        std::vector<std::string> paths;
        std::vector<NoisyMesh> meshes;
        std::vector<bool> is_path;
        for (py::handle s : scan_args) {
          if (py::isinstance<py::str>(s) || IsPathLike(s)) {
            paths.push_back(s.cast<PathArg>().string());
            is_path.push_back(true);
          } else {
            meshes.push_back(ToNoisyMesh(s, "fuse"));
            is_path.push_back(false);
          }
        }
        const size_t n = is_path.size();
        if (n == 0) throw py::value_error("fuse: no scans");
        std::vector<Eigen::Isometry3d> initial(n, Eigen::Isometry3d::Identity());
        std::vector<ScanPose> file_poses;
        std::string poses_file;
        if (py::isinstance<py::str>(poses_arg) || IsPathLike(poses_arg)) {
          if (!meshes.empty()) throw py::value_error("fuse: poses from a file need every scan given as a path");
          poses_file = poses_arg.cast<PathArg>().string();
        } else if (!poses_arg.is_none()) {
          if (!py::isinstance<py::sequence>(poses_arg)) {
            throw py::type_error("fuse: poses must be None, a pose file or a list of 4x4 matrices");
          }
          const py::sequence seq = poses_arg.cast<py::sequence>();
          if (seq.size() != n) {
            throw py::value_error("fuse: " + std::to_string(seq.size()) + " poses for " + std::to_string(n) + " scans");
          }
          for (size_t k = 0; k < n; ++k) initial[k] = PoseFromArray(seq[k], k);
        }

        std::vector<Scan> scans;
        ModelSummary summary;
        Mesh model;
        std::vector<Eigen::Isometry3d> poses;
        {
          py::gil_scoped_release nogil;
          if (!poses_file.empty()) file_poses = ReadScanPoses(poses_file);
          size_t next_path = 0, next_mesh = 0;
          for (size_t k = 0; k < n; ++k) {
            if (is_path[k]) {
              const std::string& path = paths[next_path++];
              scans.push_back(ReadScan(path, scan_options));
              if (!poses_file.empty()) initial[k] = FindScanPose(file_poses, path, poses_file).world_from_scan;
            } else {
              scans.push_back(MakeScanFromMesh(meshes[next_mesh++], "scan " + std::to_string(k)));
            }
          }
          poses = PlaceScans(scans, initial, options, &summary);
          model = FuseModel(scans, poses, options, &summary);
        }
        WarnNotices(summary.notices, "fuse");
        return py::make_tuple(std::move(model), PosesToArray(poses), std::move(summary));
      },
      py::arg("scans"), py::arg("poses") = py::none(),
      R"(Aligns range scans with their covariances and fuses them into one mesh, as `rangebayes fuse` does:
(Mesh in the world frame, poses as an (n, 4, 4) array of world_from_scan, ModelSummary).
scans: file paths (PLY range grids such as the Stanford scans, or meshes) or Mesh / NoisyMesh objects.
poses: the initial poses: None (identity), a pose file in bun.conf format (scans given as paths), or n 4x4 matrices.
Keywords: align (default True; False fuses the given poses after checking them), smooth (each scan with its own
covariance before fusion), decimate, progress, and dicts of options: scan (rangebayes.SCAN_OPTIONS), registration
(REGISTER_OPTIONS), smoothing (SMOOTH_OPTIONS), fusion (FUSE_OPTIONS), decimation (DECIMATE_OPTIONS).
Raises rangebayes.Error naming the scans that do not overlap or stay misaligned. GIL released.)");
  m.attr("SCAN_OPTIONS") = FieldsToDict(ScanOptionFields(), RangeGridScanOptions{});
  m.attr("REGISTER_OPTIONS") = FieldsToDict(RegisterOptionFields(), RegisterOptions{});
  m.attr("FUSE_OPTIONS") = FieldsToDict(FuseOptionFields(), FuseOptions{});
}

}  // namespace rangebayes::python

// Multi-scan alignment and fusion (fusion/): the Stanford bunny's ten scans from perturbed reference poses, the
// fused mesh against the reference-pose union of the raw scans, and synthetic multi-view scans of a known mesh.
//
//   bench_fuse bunny DIR OUT [--seeds 1,2,3] [--smooth]   ten scans in DIR (bun.conf); writes OUT/...
//   bench_fuse score DIR POSES.conf MESH.ply               pose errors and mesh distances of any result (Open3D's)
//   bench_fuse synthetic OUT                               rendered views of a known blob with ray noise
//   bench_fuse align DIR START.conf OUT.conf [key=value..]  joint alignment from START with option overrides
//   bench_fuse sequential DIR START.conf OUT.conf           scan by scan onto the union of the ones before
//   bench_fuse residuals DIR A.conf [B.conf ...]           unweighted pair residuals of several pose sets
#include <sys/resource.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "bayes/smooth.h"
#include "bench/bench_main.h"
#include "core/error.h"
#include "core/mesh_io.h"
#include "core/scan_poses.h"
#include "core/topology.h"
#include "fusion/register.h"
#include "fusion/scan.h"
#include "fusion/synthetic_scan.h"
#include "fusion/tsdf.h"
#include "pipeline/mesh_metrics.h"

namespace rb = rangebayes;

namespace {

const char* kScans[] = {"bun000.ply", "bun045.ply", "bun090.ply", "bun180.ply", "bun270.ply",
                        "bun315.ply", "chin.ply",   "ear_back.ply", "top2.ply", "top3.ply"};

double CpuSeconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_utime.tv_sec + usage.ru_stime.tv_sec + 1e-6 * (usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
}

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return NAN;
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(q * (v.size() - 1) + 0.5));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[k];
}

double Rms(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x * x;
  return v.empty() ? NAN : std::sqrt(s / v.size());
}

struct Bunny {
  std::vector<rb::Scan> scans;
  std::vector<Eigen::Isometry3d> reference;
};

Bunny ReadBunny(const std::string& dir) {
  Bunny b;
  const std::vector<rb::ScanPose> conf = rb::ReadScanPoses(dir + "/bun.conf");
  for (const char* name : kScans) {
    b.scans.push_back(rb::ReadScan(dir + "/" + name));
    b.reference.push_back(rb::FindScanPose(conf, name, "bun.conf").world_from_scan);
  }
  return b;
}

// Every vertex on a triangle of every scan, placed with the reference poses.
rb::Vertices ReferenceUnion(const Bunny& b, int stride) {
  std::vector<double> xyz;
  for (size_t s = 0; s < b.scans.size(); ++s) {
    const rb::Scan& scan = b.scans[s];
    for (int i = 0; i < scan.num_vertices(); i += stride) {
      if (scan.normal.row(i).squaredNorm() < 0.5) continue;
      const Eigen::Vector3d p = b.reference[s] * Eigen::Vector3d(scan.noisy.mesh.V.row(i));
      xyz.insert(xyz.end(), {p.x(), p.y(), p.z()});
    }
  }
  return Eigen::Map<const rb::Vertices>(xyz.data(), static_cast<Eigen::Index>(xyz.size() / 3), 3);
}

struct PoseStats {
  double max_deg = 0, max_translation = 0;
};

PoseStats Errors(const std::vector<Eigen::Isometry3d>& estimate, const std::vector<Eigen::Isometry3d>& reference) {
  PoseStats out;
  for (size_t k = 1; k < estimate.size(); ++k) {
    const rb::PoseError e = rb::RelativePoseError(estimate[0], estimate[k], reference[0], reference[k]);
    out.max_deg = std::max(out.max_deg, e.rotation_deg);
    out.max_translation = std::max(out.max_translation, e.translation);
  }
  return out;
}

// Distances of the reference union to a mesh (placed so that its bun000 matches the reference's).
void ScoreMesh(const rb::Mesh& mesh, const rb::Vertices& union_points, const char* label) {
  const Eigen::VectorXd d = rb::DistanceToSurface(union_points, mesh);
  std::vector<double> v(d.data(), d.data() + d.size());
  int within = 0;
  for (double x : v) within += x <= 1e-3;
  std::printf("%s: raw points to mesh RMS %.4f mm, p95 %.4f mm, median %.4f mm, within 1 mm %.2f%%; mesh %d faces, "
              "%d boundary edges\n",
              label, 1e3 * Rms(v), 1e3 * Percentile(v, 0.95), 1e3 * Percentile(v, 0.5), 100.0 * within / v.size(),
              mesh.num_faces(), rb::CountBoundaryEdges(mesh));
}

Eigen::Isometry3d Perturb(const Eigen::Isometry3d& pose, const Eigen::Vector3d& centre, std::mt19937_64* rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0), angle(0.0, 5.0), shift(0.0, 0.01);
  Eigen::Vector3d axis, dir;
  do axis = Eigen::Vector3d(u(*rng), u(*rng), u(*rng)); while (axis.norm() > 1 || axis.norm() < 1e-3);
  do dir = Eigen::Vector3d(u(*rng), u(*rng), u(*rng)); while (dir.norm() > 1 || dir.norm() < 1e-3);
  Eigen::Isometry3d delta = Eigen::Isometry3d::Identity();
  delta.linear() = Eigen::AngleAxisd(angle(*rng) * M_PI / 180, axis.normalized()).toRotationMatrix();
  // Rotation about the scan's world centroid, then a shift of up to 1 cm.
  delta.translation() = centre - delta.linear() * centre + shift(*rng) * dir.normalized();
  return delta * pose;
}

void WritePoses(const std::vector<rb::Scan>& scans, const std::vector<Eigen::Isometry3d>& poses,
                const std::string& path) {
  std::vector<rb::ScanPose> out;
  for (size_t k = 0; k < scans.size(); ++k) out.push_back({kScans[k], poses[k]});
  rb::WriteScanPoses(out, path);
}

int RunBunny(const std::string& dir, const std::string& out, const std::vector<int>& seeds, bool smooth) {
  std::filesystem::create_directories(out);
  double cpu0 = CpuSeconds();
  auto wall0 = std::chrono::steady_clock::now();
  const Bunny b = ReadBunny(dir);
  const double read_cpu = CpuSeconds() - cpu0;
  const double read_wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  std::printf("read and triangulated 10 scans: %.2f s wall, %.2f s CPU\n", read_wall, read_cpu);
  // Inputs for the Open3D peer: each scan's points and normals in its own frame.
  for (size_t k = 0; k < b.scans.size(); ++k) {
    rb::Mesh points;
    points.V = b.scans[k].noisy.mesh.V;
    points.N = b.scans[k].normal;
    points.F = b.scans[k].noisy.mesh.F;
    rb::WriteMesh(points, out + "/" + kScans[k]);
  }
  std::vector<Eigen::Isometry3d> first_result;
  for (int seed : seeds) {
    std::mt19937_64 rng(static_cast<std::uint64_t>(seed));
    std::vector<Eigen::Isometry3d> start = b.reference;
    for (size_t k = 1; k < start.size(); ++k) {
      Eigen::Vector3d centre = Eigen::Vector3d::Zero();
      const rb::Vertices& V = b.scans[k].noisy.mesh.V;
      for (int i = 0; i < V.rows(); ++i) centre += b.reference[k] * Eigen::Vector3d(V.row(i));
      start[k] = Perturb(b.reference[k], centre / V.rows(), &rng);
    }
    WritePoses(b.scans, start, out + "/start_seed" + std::to_string(seed) + ".conf");
    const PoseStats before = Errors(start, b.reference);
    cpu0 = CpuSeconds();
    wall0 = std::chrono::steady_clock::now();
    rb::RegisterSummary summary;
    const std::vector<Eigen::Isometry3d> poses = rb::RegisterScans(b.scans, start, {}, &summary);
    const double cpu = CpuSeconds() - cpu0;
    const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
    const PoseStats after = Errors(poses, b.reference);
    std::printf("seed %d: start worst %.2f deg / %.2f mm -> aligned worst %.4f deg / %.4f mm; %.2f s wall, %.2f s CPU "
                "(%d iterations)\n",
                seed, before.max_deg, 1e3 * before.max_translation, after.max_deg, 1e3 * after.max_translation, wall,
                cpu, summary.iterations);
    for (size_t k = 1; k < poses.size(); ++k) {
      const rb::PoseError e = rb::RelativePoseError(poses[0], poses[k], b.reference[0], b.reference[k]);
      std::printf("  %-12s %.4f deg %.4f mm\n", kScans[k], e.rotation_deg, 1e3 * e.translation);
    }
    WritePoses(b.scans, poses, out + "/ours_seed" + std::to_string(seed) + ".conf");
    if (first_result.empty()) {
      first_result = poses;
      std::FILE* f = std::fopen((out + "/report_seed" + std::to_string(seed) + ".txt").c_str(), "w");
      if (f) {
        std::fputs(rb::FormatPairReport(summary, b.scans).c_str(), f);
        std::fclose(f);
      }
    }
  }
  // Fusion with the first seed's poses (bun000 is the identity in both).
  cpu0 = CpuSeconds();
  wall0 = std::chrono::steady_clock::now();
  rb::FuseSummary fs;
  const rb::NoisyMesh fused = rb::FuseScans(b.scans, first_result, {}, &fs);
  const double fcpu = CpuSeconds() - cpu0;
  const double fwall = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  std::printf("fusion: %s; %.2f s wall, %.2f s CPU\n", fs.BriefReport().c_str(), fwall, fcpu);
  rb::WriteMesh(fused.mesh, out + "/ours_fused.ply");
  const rb::Vertices union_points = ReferenceUnion(b, 4);
  ScoreMesh(fused.mesh, union_points, "ours (TSDF)");
  if (smooth) {
    cpu0 = CpuSeconds();
    wall0 = std::chrono::steady_clock::now();
    std::vector<rb::Scan> smoothed;
    int iterations = 0;
    for (const rb::Scan& scan : b.scans) {
      rb::SmoothSummary ss;
      smoothed.push_back(rb::SmoothScan(scan, {}, &ss));
      iterations += ss.iterations;
    }
    const rb::NoisyMesh fused_smoothed = rb::FuseScans(smoothed, first_result, {}, nullptr);
    std::printf("scans smoothed (%d iterations in all), then fused: %.2f s wall, %.2f s CPU\n", iterations,
                std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count(), CpuSeconds() - cpu0);
    rb::WriteMesh(fused_smoothed.mesh, out + "/ours_fused_smoothed.ply");
    ScoreMesh(fused_smoothed.mesh, union_points, "ours (scans smoothed, TSDF)");
  }
  return 0;
}

int RunScore(const std::string& dir, const std::string& conf, const std::string& mesh_path) {
  const Bunny b = ReadBunny(dir);
  const std::vector<rb::ScanPose> poses = rb::ReadScanPoses(conf);
  std::vector<Eigen::Isometry3d> estimate;
  for (const char* name : kScans) estimate.push_back(rb::FindScanPose(poses, name, conf).world_from_scan);
  const PoseStats e = Errors(estimate, b.reference);
  std::printf("%s: worst pose error %.4f deg / %.4f mm\n", conf.c_str(), e.max_deg, 1e3 * e.max_translation);
  for (size_t k = 1; k < estimate.size(); ++k) {
    const rb::PoseError pe = rb::RelativePoseError(estimate[0], estimate[k], b.reference[0], b.reference[k]);
    std::printf("  %-12s %.4f deg %.4f mm\n", kScans[k], pe.rotation_deg, 1e3 * pe.translation);
  }
  if (!mesh_path.empty()) {
    rb::Mesh mesh = rb::ReadMesh(mesh_path);
    // The mesh is in the frame of the estimate's bun000: move it to the reference's.
    const Eigen::Isometry3d to_reference = b.reference[0] * estimate[0].inverse();
    for (int i = 0; i < mesh.num_vertices(); ++i) mesh.V.row(i) = to_reference * Eigen::Vector3d(mesh.V.row(i));
    ScoreMesh(mesh, ReferenceUnion(b, 4), mesh_path.c_str());
  }
  return 0;
}

// Views of a known blob (about 10 cm across) with noise along the rays; fused with the true poses and after
// alignment from perturbed ones.
int RunSynthetic(const std::string& out) {
  std::filesystem::create_directories(out);
  rb::Mesh truth = rb::MakeSphereMesh(0.05, Eigen::Vector3d::Zero(), 160);
  for (int i = 0; i < truth.num_vertices(); ++i) {
    const Eigen::Vector3d p = truth.V.row(i);
    const double theta = std::acos(std::clamp(p.z() / p.norm(), -1.0, 1.0)), phi = std::atan2(p.y(), p.x());
    truth.V.row(i) = p * (1.0 + 0.12 * std::sin(3 * theta) * std::cos(2 * phi) +
                          0.08 * std::cos(5 * phi) * std::sin(theta));
  }
  rb::WriteMesh(truth, out + "/truth.ply");
  const double sigma = 2e-4, spacing = 5e-4;
  std::vector<Eigen::Isometry3d> poses;
  for (int k = 0; k < 8; ++k) {
    Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
    p.linear() = (Eigen::AngleAxisd(2 * M_PI * k / 8, Eigen::Vector3d::UnitY()) *
                  Eigen::AngleAxisd((k % 2 ? 25.0 : -25.0) * M_PI / 180, Eigen::Vector3d::UnitX()))
                     .toRotationMatrix();
    poses.push_back(p);
  }
  for (double pitch : {90.0, -90.0}) {
    Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
    p.linear() = Eigen::AngleAxisd(pitch * M_PI / 180, Eigen::Vector3d::UnitX()).toRotationMatrix();
    poses.push_back(p);
  }
  std::vector<rb::Scan> scans;
  std::vector<double> single;
  for (size_t k = 0; k < poses.size(); ++k) {
    rb::SyntheticScanOptions so;
    so.width = so.height = 280;
    so.spacing = spacing;
    so.sigma_range = sigma;
    so.seed = 100 + k;
    rb::RangeGridScanOptions go;
    go.sigma_range = sigma;
    go.sigma_lateral = sigma / 4;
    go.min_cos_incidence = 1.0;  // the synthetic scanner's noise does not grow at grazing incidence
    scans.push_back(rb::MakeRangeGridScan(rb::RenderSyntheticScan(truth, poses[k], so), "view" + std::to_string(k),
                                          go));
  }
  // A single scan's points against the truth.
  {
    rb::Vertices pts = scans[0].noisy.mesh.V;
    for (int i = 0; i < pts.rows(); ++i) pts.row(i) = poses[0] * Eigen::Vector3d(pts.row(i));
    const Eigen::VectorXd d = rb::DistanceToSurface(pts, truth);
    single.assign(d.data(), d.data() + d.size());
  }
  const double single_median = Percentile(single, 0.5);
  std::printf("synthetic: %zu views, sigma_ray %.3g mm, grid %.3g mm; single scan points: median %.4f mm, p95 %.4f mm\n",
              poses.size(), 1e3 * sigma, 1e3 * spacing, 1e3 * single_median, 1e3 * Percentile(single, 0.95));
  const auto score = [&](const rb::Mesh& model, const char* label) {
    const Eigen::VectorXd d = rb::DistanceToSurface(model.V, truth);
    std::vector<double> v(d.data(), d.data() + d.size());
    const Eigen::VectorXd c = rb::DistanceToSurface(truth.V, model);
    int covered = 0;
    for (int i = 0; i < c.size(); ++i) covered += c(i) <= 3 * sigma;
    std::printf("  %-28s median %.4f mm (%.2fx single), p95 %.4f mm; true surface within 3 sigma: %.2f%%; "
                "%d faces, %d boundary edges\n",
                label, 1e3 * Percentile(v, 0.5), Percentile(v, 0.5) / single_median, 1e3 * Percentile(v, 0.95),
                100.0 * covered / c.size(), model.num_faces(), rb::CountBoundaryEdges(model));
  };
  rb::FuseSummary fs;
  const rb::NoisyMesh fused = rb::FuseScans(scans, poses, {}, &fs);
  std::printf("  %s\n", fs.BriefReport().c_str());
  score(fused.mesh, "fused (true poses)");
  double cpu0 = CpuSeconds();
  rb::SmoothSummary ss;
  const rb::Mesh smoothed = rb::Smooth(fused, {}, &ss);
  std::printf("  smoothing the fused mesh: %d iterations, %.2f s CPU\n", ss.iterations, CpuSeconds() - cpu0);
  score(smoothed, "fused, then smoothed");
  rb::WriteMesh(smoothed, out + "/fused_smoothed.ply");
  cpu0 = CpuSeconds();
  std::vector<rb::Scan> smoothed_scans;
  int smooth_iterations = 0;
  for (const rb::Scan& scan : scans) {
    rb::SmoothSummary one;
    smoothed_scans.push_back(rb::SmoothScan(scan, {}, &one));
    smooth_iterations += one.iterations;
  }
  const rb::NoisyMesh fused_smoothed_scans = rb::FuseScans(smoothed_scans, poses, {}, nullptr);
  std::printf("  smoothing each scan: %d iterations in all, %.2f s CPU (with fusion)\n", smooth_iterations,
              CpuSeconds() - cpu0);
  {
    rb::Vertices pts = smoothed_scans[0].noisy.mesh.V;
    for (int i = 0; i < pts.rows(); ++i) pts.row(i) = poses[0] * Eigen::Vector3d(pts.row(i));
    const Eigen::VectorXd d = rb::DistanceToSurface(pts, truth);
    std::vector<double> v(d.data(), d.data() + d.size());
    std::printf("  single scan smoothed: median %.4f mm, p95 %.4f mm\n", 1e3 * Percentile(v, 0.5),
                1e3 * Percentile(v, 0.95));
  }
  score(fused_smoothed_scans.mesh, "scans smoothed, then fused");
  rb::WriteMesh(fused_smoothed_scans.mesh, out + "/smoothed_scans_fused.ply");
  // Alignment from poses perturbed by up to 5 deg / 1 cm.
  std::mt19937_64 rng(3);
  std::vector<Eigen::Isometry3d> start = poses;
  for (size_t k = 1; k < start.size(); ++k) start[k] = Perturb(poses[k], Eigen::Vector3d::Zero(), &rng);
  rb::RegisterSummary rs;
  const std::vector<Eigen::Isometry3d> aligned = rb::RegisterScans(scans, start, {}, &rs);
  const PoseStats before = Errors(start, poses), after = Errors(aligned, poses);
  std::printf("  alignment: start worst %.2f deg / %.2f mm -> %.4f deg / %.4f mm (%s)\n", before.max_deg,
              1e3 * before.max_translation, after.max_deg, 1e3 * after.max_translation, rs.BriefReport().c_str());
  const rb::NoisyMesh fused_aligned = rb::FuseScans(scans, aligned, {}, nullptr);
  score(fused_aligned.mesh, "fused (aligned poses)");
  std::vector<rb::Scan> smoothed_for_aligned;
  for (const rb::Scan& scan : scans) smoothed_for_aligned.push_back(rb::SmoothScan(scan));
  score(rb::FuseScans(smoothed_for_aligned, aligned, {}, nullptr).mesh, "aligned, scans smoothed, fused");
  return 0;
}


// Per ordered pair of scans: distances of a's interior, non-grazing vertices (every 4th) to b's triangulated
// surface, for several pose sets on one common point set (the points within 1 mm of b under every pose set), so
// that a pose set closer to the truth shows as smaller residuals. Unweighted: no noise model involved.
int RunResiduals(const std::string& dir, const std::vector<std::string>& confs) {
  const Bunny b = ReadBunny(dir);
  std::vector<std::vector<Eigen::Isometry3d>> sets;
  for (const std::string& conf : confs) {
    const std::vector<rb::ScanPose> poses = rb::ReadScanPoses(conf);
    std::vector<Eigen::Isometry3d> estimate;
    for (const char* name : kScans) estimate.push_back(rb::FindScanPose(poses, name, conf).world_from_scan);
    sets.push_back(estimate);
  }
  const size_t n = b.scans.size(), m = sets.size();
  // Interior vertices: not within two rings of the mesh boundary.
  std::vector<std::vector<char>> near_boundary(n);
  for (size_t s = 0; s < n; ++s) {
    const rb::Mesh& mesh = b.scans[s].noisy.mesh;
    std::vector<char> mark(mesh.num_vertices(), 0);
    const rb::EdgeTopology topology = rb::ComputeEdgeTopology(mesh);
    for (int e = 0; e < topology.edges.rows(); ++e) {
      if (topology.edge_faces.size(e) == 1) mark[topology.edges(e, 0)] = mark[topology.edges(e, 1)] = 1;
    }
    for (int ring = 0; ring < 2; ++ring) {
      std::vector<char> next = mark;
      for (int f = 0; f < mesh.num_faces(); ++f) {
        const bool any = mark[mesh.F(f, 0)] || mark[mesh.F(f, 1)] || mark[mesh.F(f, 2)];
        if (any) next[mesh.F(f, 0)] = next[mesh.F(f, 1)] = next[mesh.F(f, 2)] = 1;
      }
      mark = next;
    }
    near_boundary[s] = mark;
  }
  std::vector<double> total2(m, 0.0);
  std::vector<std::vector<double>> all(m);
  long long total_count = 0;
  std::printf("# pair points  rms_mm(per pose set: %s)  median_mm\n", [&] {
    std::string names;
    for (const std::string& c : confs) names += rb::FileBaseName(c) + " ";
    return names;
  }().c_str());
  for (size_t a = 0; a < n; ++a) {
    const rb::Scan& sa = b.scans[a];
    std::vector<int> ids;
    for (int i = 0; i < sa.num_vertices(); i += 4) {
      if (near_boundary[a][i] || sa.normal.row(i).squaredNorm() < 0.5) continue;
      if (-sa.normal.row(i).dot(sa.ray.row(i)) < 0.3) continue;
      ids.push_back(i);
    }
    for (size_t c = 0; c < n; ++c) {
      if (c == a) continue;
      std::vector<Eigen::VectorXd> d(m);
      for (size_t k = 0; k < m; ++k) {
        const Eigen::Isometry3d c_from_a = sets[k][c].inverse() * sets[k][a];
        rb::Vertices pts(ids.size(), 3);
        for (size_t j = 0; j < ids.size(); ++j) pts.row(j) = c_from_a * Eigen::Vector3d(sa.noisy.mesh.V.row(ids[j]));
        d[k] = rb::DistanceToSurface(pts, b.scans[c].noisy.mesh);
      }
      std::vector<std::vector<double>> kept(m);
      for (size_t j = 0; j < ids.size(); ++j) {
        bool ok = true;
        for (size_t k = 0; k < m; ++k) ok = ok && d[k](j) < 1e-3;
        if (!ok) continue;
        for (size_t k = 0; k < m; ++k) kept[k].push_back(d[k](j));
      }
      if (kept[0].size() < 50) continue;
      total_count += kept[0].size();
      std::printf("%-9s %-9s %6zu ", kScans[a], kScans[c], kept[0].size());
      for (size_t k = 0; k < m; ++k) {
        std::printf(" %.4f", 1e3 * Rms(kept[k]));
        for (double x : kept[k]) total2[k] += x * x;
        all[k].insert(all[k].end(), kept[k].begin(), kept[k].end());
      }
      std::printf("  |");
      for (size_t k = 0; k < m; ++k) std::printf(" %.4f", 1e3 * Percentile(kept[k], 0.5));
      std::printf("\n");
    }
  }
  for (size_t k = 0; k < m; ++k) {
    std::printf("%s: %lld points, RMS %.4f mm, median %.4f mm, p90 %.4f mm\n", confs[k].c_str(), total_count,
                1e3 * std::sqrt(total2[k] / total_count), 1e3 * Percentile(all[k], 0.5), 1e3 * Percentile(all[k], 0.9));
  }
  return 0;
}


// Alignment from a given pose file with option overrides key=value (for the sensitivity runs in the journal).
int RunAlign(const std::string& dir, const std::string& start_conf, const std::string& out_conf,
             const std::vector<std::string>& overrides) {
  rb::RangeGridScanOptions so;
  rb::RegisterOptions ro;
  for (const std::string& kv : overrides) {
    const size_t eq = kv.find('=');
    RB_CHECK(eq != std::string::npos, "override ", kv, " is not key=value");
    const std::string key = kv.substr(0, eq), value = kv.substr(eq + 1);
    const double v = std::stod(value);
    if (key == "sigma_range") so.sigma_range = v;
    else if (key == "sigma_lateral") so.sigma_lateral = v;
    else if (key == "slide") ro.slide_sigma_edges = v;
    else if (key == "robust") ro.robust_scale_sigma = v;
    else if (key == "normal_angle") ro.max_normal_angle_deg = v;
    else if (key == "samples") ro.samples_per_scan = static_cast<int>(v);
    else if (key == "final_samples") ro.final_samples_per_scan = static_cast<int>(v);
    else if (key == "iterations") ro.iterations_per_level = static_cast<int>(v);
    else if (key == "seed") ro.seed = static_cast<std::uint64_t>(v);
    else if (key == "last_level") ro.max_distance_edges.back() = v;
    else if (key == "rings") ro.boundary_rings = static_cast<int>(v);
    else if (key == "min_cos") so.min_cos_incidence = v;
    else RB_FAIL("unknown override ", key);
  }
  const std::vector<rb::ScanPose> conf = rb::ReadScanPoses(dir + "/bun.conf");
  const std::vector<rb::ScanPose> start_file = rb::ReadScanPoses(start_conf);
  std::vector<rb::Scan> scans;
  std::vector<Eigen::Isometry3d> reference, start;
  for (const char* name : kScans) {
    scans.push_back(rb::ReadScan(dir + "/" + name, so));
    reference.push_back(rb::FindScanPose(conf, name, "bun.conf").world_from_scan);
    start.push_back(rb::FindScanPose(start_file, name, start_conf).world_from_scan);
  }
  const double cpu0 = CpuSeconds();
  rb::RegisterSummary summary;
  const std::vector<Eigen::Isometry3d> poses = rb::RegisterScans(scans, start, ro, &summary);
  const PoseStats after = Errors(poses, reference);
  std::printf("aligned worst %.4f deg / %.4f mm (%.1f s CPU; %s)\n", after.max_deg, 1e3 * after.max_translation,
              CpuSeconds() - cpu0, summary.BriefReport().c_str());
  for (size_t k = 1; k < poses.size(); ++k) {
    const rb::PoseError e = rb::RelativePoseError(poses[0], poses[k], reference[0], reference[k]);
    std::printf("  %-12s %.4f deg %.4f mm\n", kScans[k], e.rotation_deg, 1e3 * e.translation);
  }
  WritePoses(scans, poses, out_conf);
  return 0;
}


// Sequential alignment, for the joint-vs-sequential comparison: scan k is registered (our pairwise GICP) to the
// union of scans 0..k−1 as already placed, in the order of kScans; no global refinement afterwards.
int RunSequential(const std::string& dir, const std::string& start_conf, const std::string& out_conf) {
  const Bunny b = ReadBunny(dir);
  const std::vector<rb::ScanPose> start_file = rb::ReadScanPoses(start_conf);
  std::vector<Eigen::Isometry3d> poses;
  for (const char* name : kScans) poses.push_back(rb::FindScanPose(start_file, name, start_conf).world_from_scan);
  const double cpu0 = CpuSeconds();
  for (size_t k = 1; k < b.scans.size(); ++k) {
    rb::Scan merged;
    merged.name = "scans before " + std::string(kScans[k]);
    int nv = 0, nf = 0;
    for (size_t j = 0; j < k; ++j) {
      nv += b.scans[j].num_vertices();
      nf += b.scans[j].noisy.mesh.num_faces();
    }
    merged.noisy.mesh.V.resize(nv, 3);
    merged.noisy.mesh.F.resize(nf, 3);
    merged.ray.resize(nv, 3);
    merged.normal.resize(nv, 3);
    int v0 = 0, f0 = 0;
    for (size_t j = 0; j < k; ++j) {
      const rb::Scan& s = b.scans[j];
      const Eigen::Matrix3d R = poses[j].linear();
      for (int i = 0; i < s.num_vertices(); ++i) {
        merged.noisy.mesh.V.row(v0 + i) = (poses[j] * Eigen::Vector3d(s.noisy.mesh.V.row(i))).transpose();
        merged.ray.row(v0 + i) = (R * s.ray.row(i).transpose()).transpose();
        merged.normal.row(v0 + i) = (R * s.normal.row(i).transpose()).transpose();
        merged.noisy.covariance.push_back(R * s.noisy.covariance[i] * R.transpose());
      }
      merged.noisy.mesh.F.middleRows(f0, s.noisy.mesh.num_faces()) = s.noisy.mesh.F.array() + v0;
      merged.mean_edge += s.mean_edge / k;
      v0 += s.num_vertices();
      f0 += s.noisy.mesh.num_faces();
    }
    const std::vector<rb::Scan> pair = {merged, b.scans[k]};
    poses[k] = rb::RegisterScans(pair, {Eigen::Isometry3d::Identity(), poses[k]})[1];
  }
  const PoseStats after = Errors(poses, b.reference);
  std::printf("sequential: worst %.4f deg / %.4f mm (%.1f s CPU)\n", after.max_deg, 1e3 * after.max_translation,
              CpuSeconds() - cpu0);
  for (size_t k = 1; k < poses.size(); ++k) {
    const rb::PoseError e = rb::RelativePoseError(poses[0], poses[k], b.reference[0], b.reference[k]);
    std::printf("  %-12s %.4f deg %.4f mm\n", kScans[k], e.rotation_deg, 1e3 * e.translation);
  }
  WritePoses(b.scans, poses, out_conf);
  return 0;
}

int RunBench(int argc, char** argv) {
  const std::vector<std::string> args(argv + 1, argv + argc);
  if (args.size() >= 3 && args[0] == "bunny") {
    std::vector<int> seeds = {1, 2, 3};
    bool smooth = false;
    for (size_t i = 3; i < args.size(); ++i) {
      if (args[i] == "--seeds" && i + 1 < args.size()) {
        seeds.clear();
        std::stringstream list(args[++i]);
        std::string item;
        while (std::getline(list, item, ',')) seeds.push_back(std::stoi(item));
      } else if (args[i] == "--smooth") {
        smooth = true;
      }
    }
    return RunBunny(args[1], args[2], seeds, smooth);
  }
  if (args.size() >= 3 && args[0] == "score") return RunScore(args[1], args[2], args.size() > 3 ? args[3] : "");
  if (args.size() == 4 && args[0] == "sequential") return RunSequential(args[1], args[2], args[3]);
  if (args.size() >= 4 && args[0] == "align") {
    return RunAlign(args[1], args[2], args[3], std::vector<std::string>(args.begin() + 4, args.end()));
  }
  if (args.size() >= 3 && args[0] == "residuals") {
    return RunResiduals(args[1], std::vector<std::string>(args.begin() + 2, args.end()));
  }
  if (args.size() == 2 && args[0] == "synthetic") return RunSynthetic(args[1]);
  std::fprintf(stderr,
               "usage: bench_fuse bunny DIR OUT [--seeds 1,2,3] [--smooth] | score DIR POSES.conf [MESH.ply] | "
               "synthetic OUT | align DIR START.conf OUT.conf [key=value...] | sequential DIR START.conf OUT.conf | "
               "residuals DIR A.conf [B.conf...]\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) { return rangebayes::bench::Main("bench_fuse", RunBench, argc, argv); }

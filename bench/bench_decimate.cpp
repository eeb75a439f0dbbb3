// Bayesian decimation benchmarks that need only the library.
//
//   bench_decimate speed MESH LEVELS [LAMBDA]
//       decimates MESH and its midpoint subdivisions (×4 faces per level) and prints time per input face.
//   bench_decimate target SHARE MESH [MESH ...]
//       decimates MESH (several: side by side as one mesh of several components) to SHARE of its faces (--target-faces, the λ search) and prints where the time goes
//       (search partitions and triangulations, refit and shading), wall and process CPU time.
//   bench_decimate animated MESH [POSES] [SHARE] [joints|smooth]
//       bends and twists MESH into POSES poses (pose 1 the rest pose) and compares, at equal triangle count
//       (SHARE of the input faces), one patch map shared by all poses (paper §6.3) against decimating the rest
//       pose and carrying its patches to the other poses. Error per pose: area-weighted angle (degrees) between
//       each dense face normal and its patch's linear shading normal at the face centroid, the fields refitted
//       in every pose for both methods. joints (default): the bends are concentrated at two joints (a band of
//       4% of the length each, at 1/3 and 2/3 of the long axis), as in an articulated animation; smooth: one bend
//       and one twist spread evenly along the whole length (each small patch then moves almost rigidly).
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <map>
#include <string>
#include <vector>

#include "bayes/decimation/decimate.h"
#include "bench/bench_main.h"
#include "core/mesh_io.h"

namespace {

using namespace rangebayes;

Mesh Subdivide(const Mesh& m) {
  std::map<std::pair<int, int>, int> mid;
  std::vector<Eigen::RowVector3d> V;
  for (int i = 0; i < m.num_vertices(); ++i) V.push_back(m.V.row(i));
  auto midpoint = [&](int a, int b) {
    const auto key = std::minmax(a, b);
    auto it = mid.find(key);
    if (it != mid.end()) return it->second;
    V.push_back(0.5 * (m.V.row(a) + m.V.row(b)));
    return mid[key] = static_cast<int>(V.size()) - 1;
  };
  Mesh out;
  out.F.resize(4 * m.num_faces(), 3);
  for (int f = 0; f < m.num_faces(); ++f) {
    const int a = m.F(f, 0), b = m.F(f, 1), c = m.F(f, 2);
    const int ab = midpoint(a, b), bc = midpoint(b, c), ca = midpoint(c, a);
    out.F.row(4 * f) << a, ab, ca;
    out.F.row(4 * f + 1) << ab, b, bc;
    out.F.row(4 * f + 2) << ca, bc, c;
    out.F.row(4 * f + 3) << ab, bc, ca;
  }
  out.V.resize(static_cast<Eigen::Index>(V.size()), 3);
  for (size_t i = 0; i < V.size(); ++i) out.V.row(static_cast<Eigen::Index>(i)) = V[i];
  return out;
}

int Speed(const std::string& path, int levels, double lambda) {
  Mesh m = ReadMesh(path);
  std::printf("%10s %8s %8s %10s %10s %10s %10s %12s\n", "faces", "patches", "out", "partition", "geometry", "total s",
              "cpu s", "us/face");
  for (int l = 0; l <= levels; ++l) {
    if (l > 0) m = Subdivide(m);
    DecimateOptions options;
    options.lambda = lambda;
    DecimateSummary s;
    // Process CPU time beside the wall times: the library is single-threaded here, so on a loaded machine
    // the CPU time is what an idle machine's wall time would be.
    const std::clock_t c0 = std::clock();
    Decimate(m, options, &s);
    const double cpu = static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC;
    std::printf("%10d %8d %8d %10.3f %10.3f %10.3f %10.3f %12.2f\n", s.input_faces, s.num_patches, s.output_faces,
                s.seconds_partition, s.seconds_geometry, s.seconds_total, cpu, 1e6 * s.seconds_total / s.input_faces);
    std::fflush(stdout);
  }
  return 0;
}

int Target(double share, const std::vector<std::string>& paths) {
  Mesh m;
  std::string path;
  for (const std::string& p : paths) {
    const Mesh part = ReadMesh(p);
    path += (path.empty() ? "" : "+") + p;
    Mesh both;
    both.V.resize(m.num_vertices() + part.num_vertices(), 3);
    both.V << m.V, part.V;
    both.F.resize(m.num_faces() + part.num_faces(), 3);
    both.F << m.F, (part.F.array() + m.num_vertices()).matrix();
    m = std::move(both);
  }
  DecimateOptions options;
  options.target_faces = static_cast<int>(std::lround(share * m.num_faces()));
  DecimateSummary s;
  const std::clock_t c0 = std::clock();
  Decimate(m, options, &s);
  const double cpu = static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC;
  std::printf("%s: %d faces -> %d (target %d), %d patches, %d lambda steps\n", path.c_str(), s.input_faces,
              s.output_faces, options.target_faces, s.num_patches, s.bisection_steps);
  std::printf("search partition %.3f s, search geometry %.3f s, refit+shading %.3f s, total wall %.3f s, cpu %.3f s\n",
              s.seconds_search_partition, s.seconds_search_geometry, s.seconds_refit_and_shading, s.seconds_total, cpu);
  return 0;
}

// Pose m of M: along the longest bounding-box axis (t in [0, 1]) bend about a perpendicular axis by up to
// 50° and twist about the long axis by up to 60°, with phases that differ per pose; pose 0 is the rest pose.
std::vector<Mesh> MakePoses(const Mesh& rest, int count, bool joints) {
  const Eigen::RowVector3d lo = rest.V.colwise().minCoeff(), hi = rest.V.colwise().maxCoeff();
  int axis = 0;
  (hi - lo).maxCoeff(&axis);
  const int side = (axis + 1) % 3, up = (axis + 2) % 3;
  const double length = hi(axis) - lo(axis);
  const Eigen::RowVector3d centre = 0.5 * (lo + hi);
  std::vector<Mesh> poses{rest};
  for (int m = 1; m < count; ++m) {
    const double phase = 2.0 * M_PI * m / count;
    const double bend = (50.0 * M_PI / 180.0) * std::sin(phase);
    const double twist = (60.0 * M_PI / 180.0) * std::sin(2.0 * phase + 0.5);
    Mesh pose = rest;
    if (joints) {
      // Rotation about the `side` axis through each joint, applied to the part beyond it, ramped over a
      // narrow band (smoothstep) so that the surface bends there and stays rigid elsewhere.
      const double joint_t[2] = {1.0 / 3.0, 2.0 / 3.0};
      const double angle[2] = {(60.0 * M_PI / 180.0) * std::sin(phase), (60.0 * M_PI / 180.0) * std::sin(2.0 * phase + 1.0)};
      const double band = 0.04;
      Eigen::Vector3d b = Eigen::Vector3d::Zero();
      b(side) = 1.0;
      for (int v = 0; v < rest.num_vertices(); ++v) {
        const Eigen::Vector3d p0 = (rest.V.row(v) - centre).transpose();
        const double t = (p0(axis) + 0.5 * length) / length;
        Eigen::Vector3d p = p0;
        // Outer joint first, so the inner joint carries the outer part with it.
        for (int j = 1; j >= 0; --j) {
          const double x = std::clamp((t - joint_t[j]) / band + 0.5, 0.0, 1.0);
          const double ramp = x * x * (3.0 - 2.0 * x);
          Eigen::Vector3d pivot = Eigen::Vector3d::Zero();
          pivot(axis) = (joint_t[j] - 0.5) * length;
          p = Eigen::AngleAxisd(angle[j] * ramp, b) * (p - pivot) + pivot;
        }
        pose.V.row(v) = p.transpose() + centre;
      }
      poses.push_back(pose);
      continue;
    }
    for (int v = 0; v < rest.num_vertices(); ++v) {
      Eigen::Vector3d p = (rest.V.row(v) - centre).transpose();
      const double t = (p(axis) + 0.5 * length) / length;  // 0 at one end, 1 at the other
      // Twist about the long axis, growing along it.
      Eigen::Vector3d a = Eigen::Vector3d::Zero();
      a(axis) = 1.0;
      p = Eigen::AngleAxisd(twist * (t - 0.5), a) * p;
      // Bend: rotate about the `side` axis through the centre by an angle growing along the long axis.
      Eigen::Vector3d b = Eigen::Vector3d::Zero();
      b(side) = 1.0;
      p = Eigen::AngleAxisd(bend * (t - 0.5), b) * p;
      (void)up;
      pose.V.row(v) = p.transpose() + centre;
    }
    poses.push_back(pose);
  }
  return poses;
}

int Animated(const std::string& path, int count, double share, bool joints) {
  const Mesh rest = ReadMesh(path);
  const std::vector<Mesh> poses = MakePoses(rest, count, joints);
  const int target = static_cast<int>(share * rest.num_faces());
  DecimateOptions options;
  options.target_faces = target;
  DecimateSummary shared_summary;
  const std::vector<DecimatedMesh> shared = DecimateAnimated(poses, options, &shared_summary);
  // The baseline gets the shared result's triangle count, so both spend the same budget.
  options.target_faces = shared_summary.output_faces;
  DecimateSummary rest_summary;
  const DecimatedMesh alone = Decimate(rest, options, &rest_summary);
  for (size_t m = 0; m < poses.size(); ++m) {
    WriteMesh(poses[m], "/tmp/bench_decimate_pose" + std::to_string(m + 1) + ".obj");
  }
  std::printf("%s: %d faces, %d poses; shared: %d faces, %d patches; rest-pose carried: %d faces, %d patches\n",
              path.c_str(), rest.num_faces(), count, shared_summary.output_faces, shared_summary.num_patches,
              rest_summary.output_faces, rest_summary.num_patches);
  std::printf("%6s %12s %12s\n", "pose", "shared deg", "carried deg");
  double worst_shared = 0.0, worst_carried = 0.0;
  for (size_t m = 0; m < poses.size(); ++m) {
    const double a = PatchShadingErrorDeg(poses[m], shared[m].dense_face_patch);
    const double b = PatchShadingErrorDeg(poses[m], alone.dense_face_patch);
    worst_shared = std::max(worst_shared, a);
    worst_carried = std::max(worst_carried, b);
    std::printf("%6zu %12.3f %12.3f\n", m + 1, a, b);
  }
  std::printf("worst pose: shared %.3f deg, carried %.3f deg (shared is %.1f%% lower)\n", worst_shared, worst_carried,
              100.0 * (1.0 - worst_shared / worst_carried));
  return 0;
}

int RunBench(int argc, char** argv) {
  const std::string mode = argc > 1 ? argv[1] : "";
  if (mode == "speed" && argc >= 4) return Speed(argv[2], std::atoi(argv[3]), argc > 4 ? std::atof(argv[4]) : 2.0);
  if (mode == "target" && argc >= 4) return Target(std::atof(argv[2]), std::vector<std::string>(argv + 3, argv + argc));
  if (mode == "animated" && argc >= 3) {
    return Animated(argv[2], argc > 3 ? std::atoi(argv[3]) : 8, argc > 4 ? std::atof(argv[4]) : 0.05,
                    argc > 5 ? std::string(argv[5]) != "smooth" : true);
  }
  std::fprintf(stderr,
               "usage: %s speed MESH LEVELS [LAMBDA]\n       %s target SHARE MESH [MESH ...]\n"
               "       %s animated MESH [POSES] [SHARE] [joints|smooth]\n",
               argv[0], argv[0], argv[0]);
  return 2;
}

}  // namespace

// Bad input (a missing file, a wrong option or value) ends with one error line and exit code 1, not an abort.
int main(int argc, char** argv) { return rangebayes::bench::Main("bench_decimate", RunBench, argc, argv); }

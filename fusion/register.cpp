#include "fusion/register.h"

#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <memory>
#include <numeric>
#include <random>
#include <sstream>

#include "core/error.h"
#include "core/scan_poses.h"
#include "core/topology.h"

namespace rangebayes {
namespace {

Eigen::Matrix3d Skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d s;
  s << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return s;
}

// Per scan: a kd-tree over the vertices that have a normal, which of them lie on the mesh boundary, and a
// shuffled list of interior vertices to draw samples from.
struct ScanIndex {
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud;
  pcl::KdTreeFLANN<pcl::PointXYZ> tree;
  std::vector<int> tree_vertex;      // cloud point → vertex
  std::vector<char> boundary;        // per vertex
  std::vector<int> sample_order;     // interior vertices with a normal, shuffled
  Eigen::AlignedBox3d box;           // scan frame
};

void BuildIndex(const Scan& scan, std::uint64_t seed, int rings, ScanIndex* index) {
  const Mesh& mesh = scan.noisy.mesh;
  const int nv = mesh.num_vertices();
  index->boundary.assign(nv, 0);
  const EdgeTopology topology = ComputeEdgeTopology(mesh);
  for (int e = 0; e < topology.edges.rows(); ++e) {
    if (topology.edge_faces.size(e) == 1) {
      index->boundary[topology.edges(e, 0)] = 1;
      index->boundary[topology.edges(e, 1)] = 1;
    }
  }
  for (int ring = 0; ring < rings; ++ring) {
    std::vector<char> grown = index->boundary;
    for (int f = 0; f < mesh.num_faces(); ++f) {
      if (index->boundary[mesh.F(f, 0)] || index->boundary[mesh.F(f, 1)] || index->boundary[mesh.F(f, 2)]) {
        grown[mesh.F(f, 0)] = grown[mesh.F(f, 1)] = grown[mesh.F(f, 2)] = 1;
      }
    }
    index->boundary.swap(grown);
  }
  index->cloud.reset(new pcl::PointCloud<pcl::PointXYZ>);
  for (int i = 0; i < nv; ++i) {
    if (scan.normal.row(i).squaredNorm() < 0.5) continue;
    const Eigen::Vector3d p = mesh.V.row(i);
    index->cloud->push_back(pcl::PointXYZ(static_cast<float>(p.x()), static_cast<float>(p.y()),
                                          static_cast<float>(p.z())));
    index->tree_vertex.push_back(i);
    index->box.extend(p);
    if (!index->boundary[i]) index->sample_order.push_back(i);
  }
  RB_CHECK(!index->tree_vertex.empty(), scan.name, ": empty scan (no vertex on a triangle)");
  // Correspondences start from and end at interior vertices only: a scan without one overlaps nothing.
  RB_CHECK(!index->sample_order.empty(), scan.name, ": no vertex lies more than ", rings,
           " ring(s) inside the scan's boundary (", nv, " vertices): too small to align");
  index->tree.setInputCloud(index->cloud);
  std::mt19937_64 rng(seed);
  std::shuffle(index->sample_order.begin(), index->sample_order.end(), rng);
}

// Accumulated normal equations of one ordered pair: blocks for (a, a), (a, b), (b, b) and gradients.
struct PairSystem {
  Eigen::Matrix<double, 12, 12> H = Eigen::Matrix<double, 12, 12>::Zero();
  Eigen::Matrix<double, 12, 1> g = Eigen::Matrix<double, 12, 1>::Zero();
  double cost = 0;
  PairReport report;
  double sum_sigma2 = 0, sum_distance2 = 0;
};

// What stays fixed while the poses move: the scans, their indices and the constants derived from the options.
struct AlignmentProblem {
  const std::vector<Scan>& scans;
  const std::vector<ScanIndex>& index;
  const RegisterOptions& options;
  double edge;     // mean edge length over the scans, the unit of the distances in options
  double cos_max;  // cosine of the largest angle between the normals of a correspondence
  double c2;       // squared robust scale
};

// One ordered pair (a, b) at the current poses: what every correspondence of scan a against scan b shares.
struct PairFrame {
  const Scan& sa;
  const Scan& sb;
  const ScanIndex& ia;
  const ScanIndex& ib;
  Eigen::Isometry3d pose_a, pose_b;
  Eigen::Matrix3d Ra, Rb;
  Eigen::Isometry3d b_from_a;
  double slide2;
};

// Caps TBB's threads for the lifetime of the returned object; none when num_threads is 0 (all cores).
std::unique_ptr<tbb::global_control> LimitThreads(int num_threads) {
  std::unique_ptr<tbb::global_control> threads;
  if (num_threads > 0) {
    threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, num_threads);
  }
  return threads;
}

// Builds the index of every scan and returns the mean edge length over the scans.
double IndexScans(const std::vector<Scan>& scans, const RegisterOptions& options, std::vector<ScanIndex>* index) {
  const int n = static_cast<int>(scans.size());
  double edge = 0;
  for (int s = 0; s < n; ++s) {
    RB_CHECK(scans[s].normal.rows() == scans[s].num_vertices() && scans[s].ray.rows() == scans[s].num_vertices() &&
                 scans[s].noisy.has_covariance(),
             scans[s].name, ": scan lacks normals, rays or covariances");
    BuildIndex(scans[s], options.seed + static_cast<std::uint64_t>(s), options.boundary_rings, &(*index)[s]);
    edge += scans[s].mean_edge / n;
  }
  RB_CHECK(edge > 0, "alignment: the scans have no edges");
  return edge;
}

// The problem of `scans` under `options`, its indices built into *index (which it refers to).
AlignmentProblem MakeAlignmentProblem(const std::vector<Scan>& scans, const RegisterOptions& options,
                                      std::vector<ScanIndex>* index) {
  *index = std::vector<ScanIndex>(scans.size());
  const double edge = IndexScans(scans, options, index);
  return {scans, *index, options, edge, std::cos(options.max_normal_angle_deg * M_PI / 180.0),
          options.robust_scale_sigma * options.robust_scale_sigma};
}

// Pairs whose world boxes, grown by the correspondence distance, meet.
std::vector<std::pair<int, int>> OverlappingPairs(const std::vector<ScanIndex>& index,
                                                  const std::vector<Eigen::Isometry3d>& pose, double max_distance) {
  const int n = static_cast<int>(index.size());
  std::vector<std::pair<int, int>> pairs;
  std::vector<Eigen::AlignedBox3d> world_box(n);
  for (int s = 0; s < n; ++s) {
    for (int k = 0; k < 8; ++k) {
      world_box[s].extend(pose[s] * index[s].box.corner(static_cast<Eigen::AlignedBox3d::CornerType>(k)));
    }
  }
  for (int a = 0; a < n; ++a) {
    for (int b = 0; b < n; ++b) {
      if (a == b) continue;
      Eigen::AlignedBox3d grown = world_box[a];
      grown.min().array() -= max_distance;
      grown.max().array() += max_distance;
      if (grown.intersects(world_box[b])) pairs.emplace_back(a, b);
    }
  }
  return pairs;
}

// Adds the robust residual of vertex i of scan a against vertex j of scan b, weighted by both covariances plus
// sliding across b's normal nq (world frame), to the pair's normal equations and statistics.
void AddCorrespondence(const PairFrame& pair, double c2, int i, int j, const Eigen::Vector3d& nq, PairSystem* sys) {
  const Eigen::Vector3d p = pair.sa.noisy.mesh.V.row(i);
  const Eigen::Vector3d q = pair.sb.noisy.mesh.V.row(j);
  const Eigen::Matrix3d& Ra = pair.Ra;
  const Eigen::Matrix3d& Rb = pair.Rb;
  const Eigen::Vector3d xa = pair.pose_a * p, xb = pair.pose_b * q;
  const Eigen::Vector3d r = xa - xb;
  const Eigen::Matrix3d point_cov = Ra * pair.sa.noisy.covariance[i] * Ra.transpose() +
                                    Rb * pair.sb.noisy.covariance[j] * Rb.transpose();
  const Eigen::Matrix3d C = point_cov + pair.slide2 * (Eigen::Matrix3d::Identity() - nq * nq.transpose());
  const Eigen::Matrix3d W = C.inverse();
  const double e2 = r.dot(W * r);
  const double weight = 1.0 / (1.0 + e2 / c2);
  sys->cost += c2 * std::log1p(e2 / c2);
  Eigen::Matrix<double, 3, 12> J;
  J.block<3, 3>(0, 0) = -Skew(xa);
  J.block<3, 3>(0, 3).setIdentity();
  J.block<3, 3>(0, 6) = Skew(xb);
  J.block<3, 3>(0, 9) = -Eigen::Matrix3d::Identity();
  const Eigen::Matrix<double, 12, 3> JtW = J.transpose() * (weight * W);
  sys->H.noalias() += JtW * J;
  sys->g.noalias() += JtW * r;
  ++sys->report.correspondences;
  const double along = r.dot(nq);
  sys->sum_distance2 += along * along;
  sys->sum_sigma2 += along * along / nq.dot(point_cov * nq);
}

// The normal equations of the ordered pair (a, b): the first `samples` of a's shuffled interior vertices,
// each paired with its nearest interior vertex of b within max_distance whose normal agrees.
void LinearizePair(const AlignmentProblem& problem, const std::vector<Eigen::Isometry3d>& pose,
                   std::pair<int, int> ab, double max_distance, int samples, PairSystem* sys) {
  const int a = ab.first, b = ab.second;
  const Scan& sb = problem.scans[b];
  const PairFrame pair{problem.scans[a], sb, problem.index[a], problem.index[b], pose[a], pose[b],
                       pose[a].linear(), pose[b].linear(), pose[b].inverse() * pose[a],
                       std::pow(problem.options.slide_sigma_edges * sb.mean_edge, 2)};
  sys->report.a = a;
  sys->report.b = b;
  const int count = std::min<int>(samples, static_cast<int>(pair.ia.sample_order.size()));
  std::vector<int> nn(1);
  std::vector<float> nn_d2(1);
  for (int m = 0; m < count; ++m) {
    const int i = pair.ia.sample_order[m];
    const Eigen::Vector3d p = pair.sa.noisy.mesh.V.row(i);
    const Eigen::Vector3d y = pair.b_from_a * p;
    if (!(pair.ib.box.exteriorDistance(y) < max_distance)) continue;
    ++sys->report.samples;
    const pcl::PointXYZ query(static_cast<float>(y.x()), static_cast<float>(y.y()), static_cast<float>(y.z()));
    if (pair.ib.tree.nearestKSearch(query, 1, nn, nn_d2) < 1) continue;
    const int j = pair.ib.tree_vertex[nn[0]];
    if (pair.ib.boundary[j]) continue;
    const Eigen::Vector3d q = sb.noisy.mesh.V.row(j);
    if ((y - q).norm() > max_distance) continue;
    const Eigen::Vector3d np = pair.Ra * pair.sa.normal.row(i).transpose();
    const Eigen::Vector3d nq = pair.Rb * sb.normal.row(j).transpose();
    if (np.dot(nq) < problem.cos_max) continue;
    AddCorrespondence(pair, problem.c2, i, j, nq, sys);
  }
}

// The 6(n−1) normal equations of all pairs, scan 0 fixed.
struct NormalEquations {
  Eigen::MatrixXd H;
  Eigen::VectorXd g;
  double cost = 0;
};

NormalEquations Assemble(const std::vector<std::pair<int, int>>& pairs, const std::vector<PairSystem>& systems,
                         int n) {
  const int dof = 6 * (n - 1);
  NormalEquations eq;
  eq.H = Eigen::MatrixXd::Zero(dof, dof);
  eq.g = Eigen::VectorXd::Zero(dof);
  for (size_t k = 0; k < pairs.size(); ++k) {
    const int s[2] = {pairs[k].first, pairs[k].second};
    eq.cost += systems[k].cost;
    for (int u = 0; u < 2; ++u) {
      if (s[u] == 0) continue;
      eq.g.segment<6>(6 * (s[u] - 1)) += systems[k].g.segment<6>(6 * u);
      for (int v = 0; v < 2; ++v) {
        if (s[v] == 0) continue;
        eq.H.block<6, 6>(6 * (s[u] - 1), 6 * (s[v] - 1)) += systems[k].H.block<6, 6>(6 * u, 6 * v);
      }
    }
  }
  return eq;
}

// For the error of a scan that overlaps no other: when its size is far from the others' (a scan in millimetres
// among scans in metres), say so, since no pose makes it overlap.
std::string SizeHint(const std::vector<Scan>& scans, size_t s) {
  const auto diagonal = [](const Scan& scan) { return BoundingBoxExtent(scan.noisy.mesh.V).norm(); };
  std::vector<double> sizes;
  for (const Scan& scan : scans) sizes.push_back(diagonal(scan));
  std::nth_element(sizes.begin(), sizes.begin() + static_cast<std::ptrdiff_t>(sizes.size() / 2), sizes.end());
  const double median = sizes[sizes.size() / 2], ratio = diagonal(scans[s]) / median;
  if (!(median > 0) || (ratio <= 10 && ratio >= 0.1)) return "";
  char text[160];
  std::snprintf(text, sizeof(text),
                "; it is %.3g times the size of the median scan (bounding-box diagonal %.4g "
                "against %.4g): are its units those of the others?",
                ratio, diagonal(scans[s]), median);
  return text;
}

void CheckEveryScanOverlaps(const std::vector<Scan>& scans, const NormalEquations& eq, double max_distance) {
  for (int s = 1; s < static_cast<int>(scans.size()); ++s) {
    const double info = eq.H.block<6, 6>(6 * (s - 1), 6 * (s - 1)).trace();
    RB_CHECK(info > 0, scans[s].name, ": overlaps no other scan (no correspondence within ", max_distance,
             " model units); check its initial pose", SizeHint(scans, static_cast<size_t>(s)));
  }
}

// A scan given twice (the same file, or a copy under another name: the same vertices) would count its
// measurements twice in the fused model.
void CheckDistinctScans(const std::vector<Scan>& scans) {
  for (size_t j = 1; j < scans.size(); ++j) {
    for (size_t i = 0; i < j; ++i) {
      const Vertices& a = scans[i].noisy.mesh.V;
      const Vertices& b = scans[j].noisy.mesh.V;
      RB_CHECK(a.rows() != b.rows() || a != b, scans[j].name, " is the same scan as ", scans[i].name,
               " (the same vertices): give each scan once");
    }
  }
}

// Solves the damped system and applies the step to every pose but the first; returns the largest step
// (rotation in radians, translation in edge lengths).
double TakeDampedStep(double edge, NormalEquations* eq, std::vector<Eigen::Isometry3d>* pose) {
  Eigen::MatrixXd& H = eq->H;
  const double damping = 1e-9 * H.diagonal().maxCoeff();
  H.diagonal().array() += damping;
  const Eigen::VectorXd delta = -H.ldlt().solve(eq->g);
  double largest = 0;
  for (int s = 1; s < static_cast<int>(pose->size()); ++s) {
    const Eigen::Vector3d w = delta.segment<3>(6 * (s - 1));
    const Eigen::Vector3d v = delta.segment<3>(6 * (s - 1) + 3);
    Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
    if (w.norm() > 0) step.linear() = Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix();
    step.translation() = v;
    (*pose)[s] = step * (*pose)[s];
    Eigen::Matrix3d R = (*pose)[s].linear();
    (*pose)[s].linear() = Eigen::Quaterniond(R).normalized().toRotationMatrix();
    largest = std::max({largest, w.norm(), v.norm() / edge});
  }
  return largest;
}

// The overlapping pairs at `pose` and each one's normal equations within max_distance.
struct PairSystems {
  std::vector<std::pair<int, int>> pairs;
  std::vector<PairSystem> systems;
};

// done(fraction of the pairs) is called from this thread after each eighth of them (an iteration of the finest
// level takes seconds on the Stanford scans).
PairSystems LinearizeAll(const AlignmentProblem& problem, const std::vector<Eigen::Isometry3d>& pose,
                         double max_distance, int samples, const std::function<void(double)>& done) {
  PairSystems out;
  out.pairs = OverlappingPairs(problem.index, pose, max_distance);
  out.systems.resize(out.pairs.size());
  const int count = static_cast<int>(out.pairs.size());
  constexpr int kParts = 8;
  for (int part = 0; part < kParts; ++part) {
    tbb::parallel_for(count * part / kParts, count * (part + 1) / kParts, [&](int k) {
      LinearizePair(problem, pose, out.pairs[k], max_distance, samples, &out.systems[k]);
    });
    done(static_cast<double>(part + 1) / kParts);
  }
  return out;
}

// Gauss–Newton over the levels of max_distance_edges; returns the pair systems of the last iteration.
std::vector<PairSystem> Align(const AlignmentProblem& problem, std::vector<Eigen::Isometry3d>* pose,
                              RegisterSummary* local) {
  const RegisterOptions& options = problem.options;
  const int n = static_cast<int>(problem.scans.size());
  const int levels = static_cast<int>(options.max_distance_edges.size());
  std::vector<PairSystem> last;
  // Progress counts the work of an iteration as its samples per scan (the last level takes more).
  const auto level_samples = [&options, levels](int level) {
    return static_cast<double>(level + 1 == levels ? options.final_samples_per_scan : options.samples_per_scan);
  };
  double total_work = 0;
  for (int level = 0; level < levels; ++level) total_work += level_samples(level) * options.iterations_per_level;
  double work_before = 0;  // levels done
  for (int level = 0; level < levels; ++level) {
    const double max_distance = options.max_distance_edges[level] * problem.edge;
    const int samples = level + 1 == levels ? options.final_samples_per_scan : options.samples_per_scan;
    if (level + 1 == levels) local->finest_level_start = static_cast<int>(local->cost.size());
    const auto report = [&](double iterations_done) {
      if (options.progress) {
        options.progress((work_before + level_samples(level) * iterations_done) / total_work, "alignment");
      }
    };
    for (int it = 0; it < options.iterations_per_level; ++it) {
      PairSystems linear = LinearizeAll(problem, *pose, max_distance, samples, [&](double part) { report(it + part); });
      // Assemble the 6n system (scan 0 fixed) and take one damped Gauss–Newton step.
      NormalEquations eq = Assemble(linear.pairs, linear.systems, n);
      local->cost.push_back(eq.cost);
      ++local->iterations;
      last = std::move(linear.systems);
      CheckEveryScanOverlaps(problem.scans, eq, max_distance);
      const bool converged = TakeDampedStep(problem.edge, &eq, pose) < options.converged_step;
      report(converged ? options.iterations_per_level : it + 1);
      if (converged) break;
    }
    work_before += level_samples(level) * options.iterations_per_level;
    ++local->levels;
  }
  return last;
}

// A scan is not aligned when its final residuals along the normals, over all its pairs, both spread over the
// correspondence gate (RMS above kMisalignedGateShare of the last level's largest distance) and exceed their
// predicted σ many times (RMS above kMisalignedSigma): its correspondences are then chance neighbours where two
// wrongly placed surfaces cross, not one surface seen twice. Either alone is not enough: noisy meshes whose σ
// exceeds the gate spread over it when aligned, and a σ set too small inflates the σ units of aligned scans.
// Measured (docs/journal/fusion.md): aligned bunny scans 0.07–0.09 of the gate and 0.4–0.55 σ; scans 45° off
// (no --poses) 0.45–0.52 and 2.7–3.2 σ (a uniform spread over the gate gives 0.58). Blind where the noise model's
// σ exceeds the gate, as on the meshes `replay` writes (aligned 0.21–0.25 of the gate at 0.15–0.19 σ): their
// residuals say nothing beyond what the model expects.
constexpr double kMisalignedGateShare = 0.3;
constexpr double kMisalignedSigma = 2.0;

// The scans that fail the test above, as indices; *worst gets the numbers of the worst one.
std::vector<int> FindMisaligned(const AlignmentProblem& problem, const std::vector<PairSystem>& last,
                                std::string* worst) {
  const int n = static_cast<int>(problem.scans.size());
  const double gate = problem.options.max_distance_edges.back() * problem.edge;
  std::vector<double> distance2(n, 0.0), sigma2(n, 0.0);
  std::vector<int> count(n, 0);
  for (const PairSystem& sys : last) {
    for (const int s : {sys.report.a, sys.report.b}) {
      distance2[s] += sys.sum_distance2;
      sigma2[s] += sys.sum_sigma2;
      count[s] += sys.report.correspondences;
    }
  }
  std::vector<int> misaligned;
  double worst_share = 0;
  for (int s = 0; s < n; ++s) {
    if (count[s] == 0) continue;
    const double share = std::sqrt(distance2[s] / count[s]) / gate;
    const double sigma = std::sqrt(sigma2[s] / count[s]);
    if (!(share > kMisalignedGateShare && sigma > kMisalignedSigma)) continue;
    misaligned.push_back(s);
    if (share > worst_share) {
      worst_share = share;
      char line[64];
      std::snprintf(line, sizeof(line), "RMS %.2f of it, %.1f σ", share, sigma);
      *worst = line;
    }
  }
  return misaligned;
}

std::string ScanNames(const std::vector<Scan>& scans, const std::vector<int>& which) {
  std::string names;
  for (const int s : which) names += (names.empty() ? "" : ", ") + FileBaseName(scans[s].name);
  return names;
}

void CheckEveryScanAligned(const AlignmentProblem& problem, const std::vector<PairSystem>& last) {
  std::string worst;
  const std::vector<int> misaligned = FindMisaligned(problem, last, &worst);
  RB_CHECK(misaligned.empty(), ScanNames(problem.scans, misaligned), ": not aligned after registration: the ",
           "residuals spread over the whole correspondence gate (", worst, "; aligned scans give about 0.1 of it ",
           "and under 1 σ), so the initial poses are too far off: give closer ones with --poses (bun.conf format) ",
           "or leave the scan out");
}

// The pair reports of the last correspondences, sorted by pair; returns per scan the best share of its samples
// that found a partner, and its partner (−1: none).
std::pair<std::vector<double>, std::vector<int>> FillPairReports(const AlignmentProblem& problem,
                                                                 std::vector<PairSystem>* last,
                                                                 RegisterSummary* local) {
  const int n = static_cast<int>(problem.scans.size());
  std::vector<double> best_overlap(n, 0.0);
  std::vector<int> best_partner(n, -1);
  for (PairSystem& sys : *last) {
    PairReport& r = sys.report;
    if (r.correspondences == 0) continue;
    r.overlap = r.samples > 0 ? static_cast<double>(r.correspondences) / r.samples : 0.0;
    r.rms_sigma = std::sqrt(sys.sum_sigma2 / r.correspondences);
    r.rms_distance = std::sqrt(sys.sum_distance2 / r.correspondences);
    const double share = static_cast<double>(r.correspondences) /
                         std::max<size_t>(1, std::min<size_t>(problem.options.final_samples_per_scan,
                                                              problem.index[r.a].sample_order.size()));
    if (share > best_overlap[r.a]) {
      best_overlap[r.a] = share;
      best_partner[r.a] = r.b;
    }
    local->pairs.push_back(r);
  }
  std::sort(local->pairs.begin(), local->pairs.end(), [](const PairReport& x, const PairReport& y) {
    return std::make_pair(std::min(x.a, x.b), std::make_pair(std::max(x.a, x.b), x.a)) <
           std::make_pair(std::min(y.a, y.b), std::make_pair(std::max(y.a, y.b), y.a));
  });
  return {best_overlap, best_partner};
}

// Reports from the last correspondences; a scan without enough overlap, or left misaligned, is an error.
void ReportPairs(const AlignmentProblem& problem, std::vector<PairSystem>* last, RegisterSummary* local) {
  const std::vector<Scan>& scans = problem.scans;
  const RegisterOptions& options = problem.options;
  const auto [best_overlap, best_partner] = FillPairReports(problem, last, local);
  for (size_t s = 0; s < scans.size(); ++s) {
    RB_CHECK(best_overlap[s] >= options.min_overlap, scans[s].name, ": overlaps no other scan after alignment (",
             100.0 * best_overlap[s], "% of its samples found a partner",
             best_partner[s] >= 0 ? ", best " + scans[best_partner[s]].name : std::string(), "; at least ",
             100.0 * options.min_overlap, "% needed): check its pose or leave it out", SizeHint(scans, s));
  }
  CheckEveryScanAligned(problem, *last);
}

}  // namespace

void RegisterOptions::Check() const {
  RB_CHECK(!max_distance_edges.empty(), "max_distance_edges must list at least one level");
  for (double d : max_distance_edges) RB_CHECK(d > 0 && std::isfinite(d), "max_distance_edges must be positive");
  RB_CHECK(iterations_per_level >= 1 && iterations_per_level <= 1000, "iterations_per_level ",
           iterations_per_level, " is outside 1–1000");
  RB_CHECK(samples_per_scan >= 10 && samples_per_scan <= 10000000, "samples_per_scan is outside 10–1e7");
  RB_CHECK(final_samples_per_scan >= 10 && final_samples_per_scan <= 10000000,
           "final_samples_per_scan is outside 10–1e7");
  RB_CHECK(max_normal_angle_deg > 0 && max_normal_angle_deg <= 180, "max_normal_angle_deg is outside (0, 180]");
  RB_CHECK(slide_sigma_edges > 0, "slide_sigma_edges must be positive");
  RB_CHECK(robust_scale_sigma > 0, "robust_scale_sigma must be positive");
  RB_CHECK(boundary_rings >= 0 && boundary_rings <= 20, "boundary_rings ", boundary_rings, " is outside 0–20");
  RB_CHECK(min_overlap >= 0 && min_overlap < 1, "min_overlap ", min_overlap, " is outside [0, 1)");
  RB_CHECK(converged_step >= 0, "converged_step must not be negative");
  RB_CHECK(num_threads >= 0, "num_threads must not be negative");
}

std::string RegisterSummary::BriefReport() const {
  // Each level has its own gate and sample count, so only costs within one level compare: the finest level's.
  const bool finest = finest_level_start >= 0 && finest_level_start < static_cast<int>(cost.size());
  return StrCat("aligned in ", iterations, " iterations over ", levels, " levels, ", time_s, " s; cost on the finest ",
                "level ", finest ? cost[static_cast<size_t>(finest_level_start)] : 0.0, " -> ",
                cost.empty() ? 0.0 : cost.back(), "; ", pairs.size(), " overlapping pairs");
}

std::vector<Eigen::Isometry3d> RegisterScans(const std::vector<Scan>& scans,
                                             const std::vector<Eigen::Isometry3d>& initial,
                                             const RegisterOptions& options, RegisterSummary* summary) {
  options.Check();
  const auto start = std::chrono::steady_clock::now();
  const int n = static_cast<int>(scans.size());
  RB_CHECK(n >= 2, "alignment needs at least two scans, got ", n);
  RB_CHECK(static_cast<int>(initial.size()) == n, "alignment: ", initial.size(), " initial poses for ", n,
           " scans");
  CheckDistinctScans(scans);
  const std::unique_ptr<tbb::global_control> threads = LimitThreads(options.num_threads);
  std::vector<ScanIndex> index;
  const AlignmentProblem problem = MakeAlignmentProblem(scans, options, &index);
  std::vector<Eigen::Isometry3d> pose = initial;
  RegisterSummary local;
  std::vector<PairSystem> last = Align(problem, &pose, &local);
  ReportPairs(problem, &last, &local);
  local.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (summary) *summary = local;
  return pose;
}

std::string CheckPoses(const std::vector<Scan>& scans, const std::vector<Eigen::Isometry3d>& poses,
                       const RegisterOptions& options, RegisterSummary* summary) {
  options.Check();
  const int n = static_cast<int>(scans.size());
  RB_CHECK(static_cast<int>(poses.size()) == n, "pose check: ", poses.size(), " poses for ", n, " scans");
  CheckDistinctScans(scans);
  RegisterSummary local;
  if (n < 2) {
    if (summary) *summary = local;
    return {};
  }
  const std::unique_ptr<tbb::global_control> threads = LimitThreads(options.num_threads);
  std::vector<ScanIndex> index;
  const AlignmentProblem problem = MakeAlignmentProblem(scans, options, &index);
  PairSystems linear = LinearizeAll(problem, poses, options.max_distance_edges.back() * problem.edge,
                                    options.final_samples_per_scan, [&options](double part) {
                                      if (options.progress) options.progress(part, "checking the poses");
                                    });
  const std::vector<double> best_overlap = FillPairReports(problem, &linear.systems, &local).first;
  for (int s = 0; s < n; ++s) {
    if (best_overlap[s] >= options.min_overlap) continue;
    local.apart.push_back(s);
    local.apart_overlap = std::max(local.apart_overlap, best_overlap[s]);
  }
  std::string worst;
  const std::vector<int> misaligned = FindMisaligned(problem, linear.systems, &worst);
  if (summary) *summary = local;
  if (misaligned.empty()) return {};
  return StrCat(ScanNames(scans, misaligned), ": the given poses do not align ",
                misaligned.size() == 1 ? "it" : "them", " with the other scans (residuals spread over the ",
                "correspondence gate: ", worst, "; aligned scans give about 0.1 of it and under 1 σ)");
}

PoseError RelativePoseError(const Eigen::Isometry3d& estimate0, const Eigen::Isometry3d& estimate,
                            const Eigen::Isometry3d& reference0, const Eigen::Isometry3d& reference) {
  const Eigen::Isometry3d e = estimate0.inverse() * estimate;
  const Eigen::Isometry3d r = reference0.inverse() * reference;
  const Eigen::Isometry3d d = r.inverse() * e;
  PoseError out;
  out.rotation_deg = Eigen::AngleAxisd(d.linear()).angle() * 180.0 / M_PI;
  out.translation = d.translation().norm();
  return out;
}

}  // namespace rangebayes

namespace rangebayes {

std::string FormatPairReport(const RegisterSummary& summary, const std::vector<Scan>& scans) {
  std::ostringstream out;
  out << "# source target samples correspondences overlap rms_sigma rms_distance\n";
  for (const PairReport& p : summary.pairs) {
    char line[512];
    std::snprintf(line, sizeof(line), "%s %s %d %d %.3f %.3f %.6g\n", FileBaseName(scans[p.a].name).c_str(),
                  FileBaseName(scans[p.b].name).c_str(), p.samples, p.correspondences, p.overlap, p.rms_sigma,
                  p.rms_distance);
    out << line;
  }
  return out.str();
}

}  // namespace rangebayes

// The MAP smoothing energy of paper eq. 11 (docs/design.md §3.1) and its gradient (eqs. 13–16, docs/design.md §3.3):
//
//   E(x) = Σ_i (z_i − x_i)ᵀ W_i (z_i − x_i) + β Σ_(s,t) φ(‖n_s − n_t‖)
//
// x, z: #V×3 positions flattened row-major into a 3·#V vector (vertex i at [3i, 3i+3)). W_i: 3×3 symmetric
// positive semi-definite information matrix per vertex (W = ½ Σ⁻¹, units 1/length²). The prior runs over every
// pair of faces sharing an edge (ComputeFacePairs: all pairs at a non-manifold edge); β is unitless.
//
// Degenerate faces: a face with a repeated vertex index, or whose measured area is below 1e-10 of the mean
// face area, has no normal; it is left out of the prior for the whole minimisation (so E stays smooth). A face
// that becomes exactly degenerate during minimisation gets normal 0 and no gradient (never NaN).
//
// Evaluation is parallel over faces, then over vertices (TBB, in the calling arena), with per-face buffers and
// a gather per vertex in a fixed order and reductions of fixed shape: the result is bitwise identical for the
// same input whatever the thread count.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <utility>
#include <vector>

#include "bayes/potential.h"
#include "core/mesh.h"

namespace rangebayes {

struct EnergyParts {
  double data = 0;   // Σ_i r_iᵀ W_i r_i
  double prior = 0;  // β Σ φ
  double total() const { return data + prior; }
};

// Which kernels SmoothingEnergy::Evaluate runs. kAuto: AVX-512 where the CPU has it (GCC x86-64 builds), else
// portable; kPortable: always the portable ones. Both give the same bytes; the switch is for tests and benchmarks
// and must not be flipped while an evaluation runs. (AVX2 kernels measured within noise of the portable ones and
// were removed.)
enum class SmoothingKernel { kAuto, kPortable };
void SetSmoothingKernel(SmoothingKernel kernel);
// The kernels Evaluate runs now: "avx512" or "portable".
const char* SmoothingKernelName();

class SmoothingEnergy {
 public:
  // measured: z and faces (indices checked; throws Error); referenced, not copied: it must outlive this
  // object and stay unchanged. information: one W_i per vertex (symmetric). `potential` is not owned and
  // must outlive this object. prior_weight = β ≥ 0.
  //
  // face_epsilon_squared (optional, null = off): one ε² per face (size #F, each in (0, 4]; copied) for the
  // built-in square-root potential only: a pair (s, t) then costs φ(d) = sqrt(d² + ½(ε_s² + ε_t²)) instead of
  // the potential's global ε². Throws Error if `potential` is not a SqrtPotential or a value is out of range.
  SmoothingEnergy(const Mesh& measured, const std::vector<Eigen::Matrix3d>& information, double prior_weight,
                  const Potential& potential, const std::vector<double>* face_epsilon_squared = nullptr);

  // E(x) and, when gradient is not null, ∂E/∂x (resized to 3·#V). Not safe to call concurrently on one
  // object (it reuses internal buffers).
  EnergyParts Evaluate(const Eigen::VectorXd& x, Eigen::VectorXd* gradient) const;

  // Replaces the potential (not owned, must outlive this object), as the stages of an ε continuation do on one
  // energy. It must be a SqrtPotential exactly when the current one is (the kernels depend on it); Error otherwise.
  void SetPotential(const Potential& potential);

  // Heavy-tailed data term: each vertex then costs (ν/2)·log(1 + 2q_i/ν), q_i = (z_i − x_i)ᵀ W_i (z_i − x_i), instead
  // of q_i — a Student-t on the Mahalanobis distance, scaled to equal q_i for small residuals, so a gross mismatch
  // pulls with a force that falls off as 1/|r|. Its curvature never exceeds the Gaussian's, so DataCurvature and
  // ApplyDataInverse (the Gaussian's) stay an upper bound and a valid preconditioner. nu = 0: the Gaussian (the
  // default); else (0, 1e6]. Throws Error outside.
  void SetRobustData(double nu);
  double robust_data_nu() const { return data_nu_; }

  // pᵀ H_data p with H_data = blockdiag(2 W_i): the data term's curvature along p (a cheap first step length).
  double DataCurvature(const Eigen::VectorXd& p) const;

  // out = blockdiag(2 W_i)⁻¹ · v: the data term's exact Hessian inverse (computed per call, no storage).
  void ApplyDataInverse(const Eigen::VectorXd& v, Eigen::VectorXd* out) const;
  // Every W_i the same multiple of I (then ApplyDataInverse is a global scale, which CG does not need).
  bool uniform_isotropic() const { return uniform_isotropic_; }
  // 1 / (2 w) for uniform_isotropic() W = w I (the scalar ApplyDataInverse then applies); 0 otherwise.
  double UniformDataInverseScale() const;

  // The Gauss–Newton matrix of E in one direction per vertex (x_i + t_i r_i, r_i unit, 3 per vertex in `rays`),
  // an #V×#V symmetric matrix: the data term's 2 r_iᵀ W_i r_i plus β Σ_pairs J_uᵀ H_u J_u, J_u the Jacobian of
  // u = n_t − n_s in t and H_u the potential's curvature in u (for the square root (I − uuᵀ/φ²)/φ, positive
  // definite; for other potentials the weight w = φ'/d times I). The normals' second derivatives are left out, so
  // it is positive semi-definite. With a robust data term (SetRobustData) the data part is still the Gaussian's, an
  // upper bound of its curvature.
  //
  // Its entries depend on the connectivity only: RayPattern lists them (row ≤ column, repeated where several
  // pairs add to one entry) in the order in which RayGaussNewton writes their values, so that a caller assembles
  // the matrix once and refills it in place.
  struct RayPattern {
    std::vector<std::pair<int, int>> entries;  // (row, column), row ≤ column; the #V diagonals first
    std::vector<size_t> face_offsets;          // #F + 1: the first value of face t's pairs (t < s); the last: all
  };
  RayPattern RayGaussNewtonPattern() const;
  // values: one per entry (resized to pattern.face_offsets.back(); `entries` itself is not read, so a caller may
  // drop it once it has placed them).
  void RayGaussNewton(const Eigen::VectorXd& x, const std::vector<double>& rays, const RayPattern& pattern,
                      std::vector<double>* values) const;
  // The vertices where the prior is stiff at x: the prior's stiffness at vertex i is the 3×3 block B_i = β Σ_t w_t
  // A_tkᵀ A_tk over the active faces t at corner k of the vertex, A_tk = P_t [e_k]_× / |c_t| the Jacobian of t's
  // unit normal in that corner and w_t = Σ_s φ'(d_ts)/d_ts over t's neighbours s (the IRLS weights, which
  // majorise the potential's curvature: the square root's own curvature vanishes along u, where a sliver's normal
  // turns; the pairs' cross terms are left out). Its trace goes as |e|² / |c|²: slivers make it huge. Lists the
  // vertices whose trace exceeds relative_cut × the median vertex's (ascending), with their B_i.
  void StiffVertices(const Eigen::VectorXd& x, double relative_cut, std::vector<int>* vertices,
                     std::vector<Eigen::Matrix3d>* blocks) const;

  // W_i of vertex i (symmetric).
  Eigen::Matrix3d InformationMatrix(int i) const {
    double w[6];
    Information(i, w);
    Eigen::Matrix3d m;
    m << w[0], w[1], w[2], w[1], w[3], w[4], w[2], w[4], w[5];
    return m;
  }

  // The measurements as the starting state.
  Eigen::VectorXd Measurements() const;

  // Unit face normals of x (#F×3; zero rows for degenerate faces).
  Normals FaceNormals(const Eigen::VectorXd& x) const;

  // Faces of x folded over their neighbours: the face normal points against the sum of its edge-neighbours'
  // normals (a fold or flip in the result). Faces without active neighbours are not counted.
  int CountFoldedFaces(const Eigen::VectorXd& x) const;

  // A lower bound of the energy over all states: the data term is never negative, and each pair's prior term is at
  // least β · min over d in [0, 2] of φ(d) (sampled; 0 when φ is never negative, as for every built-in potential).
  // Bounds the distance to the optimum, E − E* ≤ E − LowerBound().
  double LowerBound() const;

  int num_vertices() const { return num_vertices_; }
  int num_faces() const { return static_cast<int>(faces_.rows()); }
  int num_pairs() const { return static_cast<int>(neighbours_.size() / 2); }
  int num_inactive_faces() const { return num_inactive_faces_; }
  // Bytes held by this object beyond the mesh it was built from (for memory reports).
  size_t MemoryBytes() const;

 private:
  // The constructor's steps, in this order.
  void SetFaceEpsilonSquared(const std::vector<double>& face_epsilon_squared);
  void SetInformation(const std::vector<Eigen::Matrix3d>& information);
  void MarkActiveFaces();
  void BuildCorners();
  void BuildFaceNeighbours();
  void ComputeNormals(const double* x) const;
  // Evaluate's passes after ComputeNormals: the prior sum (before β) and, when want_gradient, the corner
  // contributions into h_; then the data sum and, when grad is not null, the gradient (3 per vertex).
  double PriorPass(const double* x, bool want_gradient) const;
  double PortablePriorPass(const double* x, bool want_gradient) const;
  double DataPass(const double* x, double* grad) const;
  // h_ holds h_t alone (3 per face) and the vertex gather forms the corner products: the square-root potential
  // (global or per-face ε²), on either kernel. Other potentials keep the three products (9 per face).
  bool ThreePerFace() const;
  // ε² of pair (t, s) for the square root (the global one, or the mean of the two faces'); 0 for other potentials.
  double PairEpsilonSquared(const SqrtPotential* sqrt_potential, int t, int s) const;
  void BuildCornerEdges() const;

  int num_vertices_ = 0;
  const Faces& faces_;
  Eigen::Map<const Eigen::VectorXd> z_;  // the measured V, row-major: vertex i at [3i, 3i+3)
  // W_i: 6 per vertex (xx xy xz yy yz zz), or 1 per vertex (w_i of W_i = w_i I) when isotropic_.
  std::vector<double> information_;
  bool isotropic_ = false;
  bool uniform_isotropic_ = false;
  void Information(int i, double* w) const {
    if (isotropic_) {
      const double v = information_[static_cast<size_t>(i)];
      w[0] = w[3] = w[5] = v;
      w[1] = w[2] = w[4] = 0;
    } else {
      const double* p = &information_[6 * static_cast<size_t>(i)];
      for (int k = 0; k < 6; ++k) w[k] = p[k];
    }
  }
  double prior_weight_ = 0;
  double data_nu_ = 0;  // SetRobustData; 0: Gaussian
  const Potential* potential_ = nullptr;
  // Per-face ε² of the square-root potential (empty: the potential's own, global ε²).
  std::vector<double> face_epsilon_squared_;
  // Face neighbours (compressed rows over faces, neighbours ascending) of active faces only.
  std::vector<int> neighbour_offsets_;
  std::vector<int> neighbours_;
  std::vector<char> active_;
  int num_inactive_faces_ = 0;
  // Per vertex, its corners 3·f + k in ascending order (the fixed gather order).
  std::vector<int> corner_offsets_;
  std::vector<int> corners_;
  // Wide path only: per corner (same order) the two vertices of the edge opposite it.
  mutable std::vector<int> corner_edges_;
  // Scratch: unit normals and 1/|c_t| per face, then the gradient's three corner contributions per face (9),
  // or h_t alone (3) on the wide path.
  mutable std::vector<double> normals_;
  mutable std::vector<double> inverse_length_;
  mutable std::vector<double> h_;
};

}  // namespace rangebayes

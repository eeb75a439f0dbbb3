#include "fusion/tsdf.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <string>

#include "core/error.h"
#include "synthetic.h"

namespace rangebayes {
namespace {

// Two opposite noisy views of a sphere fuse into one surface close to it.
TEST(Fuse, TwoViewsOfASphereLieOnTheSphere) {
  const double radius = 0.04, sigma = 2e-4;
  const Mesh truth = MakeSphereMesh(radius, Eigen::Vector3d::Zero(), 96);
  const std::vector<Eigen::Isometry3d> poses = {testing::ViewPose(0), testing::ViewPose(180)};
  const std::vector<Scan> scans = testing::RenderViews(truth, poses, sigma, 80, 1.2e-3);
  FuseSummary summary;
  const NoisyMesh fused = FuseScans(scans, poses, {}, &summary);
  ASSERT_GT(fused.mesh.num_faces(), 1000) << summary.BriefReport();
  EXPECT_TRUE(fused.has_covariance());
  std::vector<double> error;
  for (int i = 0; i < fused.mesh.num_vertices(); ++i) error.push_back(std::abs(fused.mesh.V.row(i).norm() - radius));
  std::sort(error.begin(), error.end());
  const double median = error[error.size() / 2];
  // Single-scan points are off by σ·0.67 (median |N(0, σ)|); averaging over a kernel of ~5 points and
  // marching-cubes interpolation must do better; the 95th percentile stays within 3σ.
  EXPECT_LT(median, 0.67 * sigma) << summary.BriefReport();
  EXPECT_LT(error[error.size() * 95 / 100], 3 * sigma);
  // Outward normals: the first face's normal points away from the centre.
  const Eigen::Vector3d a = fused.mesh.V.row(fused.mesh.F(0, 0)), b = fused.mesh.V.row(fused.mesh.F(0, 1)),
                        c = fused.mesh.V.row(fused.mesh.F(0, 2));
  EXPECT_GT((b - a).cross(c - a).dot(a), 0);
}

// A voxel far too small for the scene is refused by the size guard: at 1e-12 of the sphere's size the grid's int
// sides overflowed, the wrapped count passed the guard, and std::vector's own "cannot create std::vector larger
// than max_size()" was the error.
TEST(Fuse, VoxelFarTooSmallIsRefusedByTheGuard) {
  const Mesh truth = MakeSphereMesh(0.04, Eigen::Vector3d::Zero(), 24);
  const std::vector<Eigen::Isometry3d> poses = {testing::ViewPose(0)};
  const std::vector<Scan> scans = testing::RenderViews(truth, poses, 2e-4, 20, 1.2e-3);
  for (const double voxel : {1e-6, 1e-14}) {
    FuseOptions options;
    options.voxel_size = voxel;
    try {
      FuseScans(scans, poses, options);
      ADD_FAILURE() << "voxel " << voxel << " was accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("exceed max_voxels"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace rangebayes

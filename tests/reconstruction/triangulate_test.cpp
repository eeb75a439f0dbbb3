// Organized triangulation: grid topology, discontinuities, downsampling, covariance shape and calibration.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>

#include "core/error.h"
#include "reconstruction/triangulate.h"
#include "stereo/spacetime_matcher.h"
#include "stereo/synth.h"

namespace rangebayes {
namespace {

DepthFrame PlaneFrame(int w, int h, double z, double sigma_d = 0.1) {
  const cv::Mat d(h, w, CV_32F, cv::Scalar(100.0 * 0.1 / z));
  const cv::Mat s(h, w, CV_32F, cv::Scalar(sigma_d));
  CameraIntrinsics k{100.0, 100.0, 0.5 * (w - 1), 0.5 * (h - 1), w, h};
  return DepthFromDisparity(d, s, k, 0.1, 0.0);
}

TEST(Triangulate, GridGivesTwoTrianglesPerBlockFacingTheCamera) {
  const DepthFrame f = PlaneFrame(4, 3, 1.0);
  TriangulateSummary s;
  const NoisyMesh m = TriangulateDepth(f, {}, &s);
  EXPECT_EQ(m.mesh.num_vertices(), 12);
  EXPECT_EQ(m.mesh.num_faces(), 2 * 3 * 2);
  EXPECT_EQ(s.cut_edges, 0);
  ASSERT_EQ(m.pixel.rows(), 12);
  for (int i = 0; i < 12; ++i) {
    EXPECT_NEAR(m.mesh.V(i, 2), 1.0, 1e-6);
    EXPECT_FLOAT_EQ(m.pixel(i, 0), static_cast<float>(i % 4));
    EXPECT_FLOAT_EQ(m.pixel(i, 1), static_cast<float>(i / 4));
  }
  for (int t = 0; t < m.mesh.num_faces(); ++t) {
    const Eigen::Vector3d a = m.mesh.V.row(m.mesh.F(t, 0)), b = m.mesh.V.row(m.mesh.F(t, 1)),
                          c = m.mesh.V.row(m.mesh.F(t, 2));
    EXPECT_LT((b - a).cross(c - a).z(), 0.0) << "face " << t << " does not face the camera";
  }
}

TEST(Triangulate, CutsDepthJumpsButKeepsTiltedPlanesAndHoles) {
  DepthFrame f = PlaneFrame(6, 4, 1.0);
  // A step of 20 cm between columns 2 and 3: far beyond σ_Z = Z²/(fB)·σ_d = 1 cm.
  for (int y = 0; y < 4; ++y)
    for (int x = 3; x < 6; ++x) f.depth_m.at<float>(y, x) = 1.2f;
  TriangulateSummary s;
  NoisyMesh m = TriangulateDepth(f, {}, &s);
  EXPECT_EQ(m.mesh.num_faces(), 2 * 3 * (2 + 2));
  EXPECT_EQ(s.cut_edges, 4);
  // A hole removes the faces around it.
  f.depth_m.at<float>(1, 1) = std::numeric_limits<float>::quiet_NaN();
  m = TriangulateDepth(f, {}, &s);
  EXPECT_EQ(m.mesh.num_vertices(), 23);
  EXPECT_EQ(m.mesh.num_faces(), 2 * 3 * (2 + 2) - 6 + 2);  // 4 blocks lose 6 faces, 4 of them keep one
  // A plane tilted 60° away from the camera changes depth by several σ per pixel and stays whole.
  DepthFrame tilt = PlaneFrame(8, 8, 1.0, 0.01);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 8; ++x) tilt.depth_m.at<float>(y, x) = static_cast<float>(1.0 + 0.0173 * x);
  m = TriangulateDepth(tilt, {}, &s);
  EXPECT_EQ(s.cut_edges, 0);
  EXPECT_EQ(m.mesh.num_faces(), 2 * 7 * 7);
}

TEST(Triangulate, DownsamplingKeepsFullResolutionPixels) {
  const DepthFrame f = PlaneFrame(9, 7, 2.0);
  TriangulateOptions o;
  o.downsample = 4;
  const NoisyMesh m = TriangulateDepth(f, o);
  EXPECT_EQ(m.mesh.num_vertices(), 3 * 2);
  EXPECT_EQ(m.mesh.num_faces(), 2 * 2 * 1);
  EXPECT_FLOAT_EQ(m.pixel(5, 0), 8.0f);
  EXPECT_FLOAT_EQ(m.pixel(5, 1), 4.0f);
}

TEST(Triangulate, CovarianceIsRayAlignedAndPositiveDefinite) {
  const DepthFrame f = PlaneFrame(20, 10, 1.5, 0.2);
  const NoisyMesh m = TriangulateDepth(f);
  ASSERT_TRUE(m.has_covariance());
  const double f_px = 100.0, b = 0.1;
  for (int i = 0; i < m.mesh.num_vertices(); i += 7) {
    const Eigen::Matrix3d& c = m.covariance[i];
    EXPECT_LT((c - c.transpose()).norm(), 1e-15);
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(c);
    EXPECT_GT(eig.eigenvalues()(0), 0.0);
    const Eigen::Vector3d p = m.mesh.V.row(i);
    const Eigen::Vector3d r = p.normalized();
    const double sigma_z = 1.5 * 1.5 / (f_px * b) * 0.2;
    EXPECT_NEAR(std::sqrt(r.dot(c * r)), sigma_z / r.z(), 1e-6 * sigma_z);  // depth is stored as float
    const Eigen::Vector3d across = r.cross(Eigen::Vector3d::UnitY()).normalized();
    EXPECT_NEAR(std::sqrt(across.dot(c * across)), p.norm() / f_px * 0.2, 1e-9);
  }
}

TEST(Triangulate, BadInputThrows) {
  DepthFrame empty;
  EXPECT_THROW(TriangulateDepth(empty), Error);
  DepthFrame f = PlaneFrame(5, 5, 1.0);
  f.intrinsics.width = 6;
  EXPECT_THROW(TriangulateDepth(f), Error);
  TriangulateOptions o;
  o.downsample = 0;
  EXPECT_THROW(TriangulateDepth(PlaneFrame(5, 5, 1.0), o), Error);
}

// The covariance is honest when the normalised residuals r = (true − measured)ᵀ Σ⁻¹ (true − measured) of a
// scan of a known scene average the number of dimensions their errors live in. A stereo vertex errs only
// along its pixel's ray (the pixel is exact in a rendered scene), so r averages 1 here, and 3 ± 0.5 for a
// 3-D error maps to 1 ± 1/6. Gross mismatches (r > 25, i.e. beyond 5σ) are outliers the Gaussian model
// does not describe; they must stay rare and are left out of the mean.
TEST(Triangulate, NormalisedResidualsMatchTheCovariance) {
  for (const auto scene : {SynthScene::kSphere, SynthScene::kPlanes, SynthScene::kCylinder}) {
    SynthOptions so;
    so.scene = scene;
    so.frames = 8;
    so.image_noise_gray = 2.0;
    so.seed = 11;
    const SynthRecording rec = RenderSynthetic(so);
    SpaceTimeMatcherOptions mo;
    mo.min_disparity_px = 8;
    mo.num_disparities = 48;
    mo.image_noise_gray = so.image_noise_gray;
    SpaceTimeMatcher matcher(mo);
    const DisparityResult r = matcher.Match(rec.left, rec.right);
    const DepthFrame frame =
        DepthFromDisparity(r.disparity_px, r.sigma_disparity_px, rec.intrinsics, rec.rig.baseline_m(), 0.0);
    const NoisyMesh mesh = TriangulateDepth(frame);
    double sum = 0.0;
    int n = 0, outliers = 0;
    for (int i = 0; i < mesh.mesh.num_vertices(); ++i) {
      const int u = static_cast<int>(mesh.pixel(i, 0)), v = static_cast<int>(mesh.pixel(i, 1));
      const double z = rec.depth_m.at<float>(v, u);
      const Eigen::Vector3d truth((u - rec.intrinsics.cx_px) / rec.intrinsics.fx_px * z,
                                  (v - rec.intrinsics.cy_px) / rec.intrinsics.fy_px * z, z);
      const Eigen::Vector3d e = truth - mesh.mesh.V.row(i).transpose();
      const double chi2 = e.dot(mesh.covariance[i].ldlt().solve(e));
      if (chi2 > 25.0) {
        ++outliers;
        continue;
      }
      sum += chi2;
      ++n;
    }
    const double mean = sum / n;
    const double outlier_fraction = static_cast<double>(outliers) / mesh.mesh.num_vertices();
    std::printf("%s: mean normalised residual %.3f over %d vertices, %.2f%% outliers\n", ToString(scene).c_str(), mean,
                n, 100.0 * outlier_fraction);
    EXPECT_NEAR(mean, 1.0, 1.0 / 6.0) << ToString(scene);
    EXPECT_LT(outlier_fraction, 0.03) << ToString(scene);
  }
}

}  // namespace
}  // namespace rangebayes

#include "core/render.h"

#include <gtest/gtest.h>

#include "core/error.h"

namespace rangebayes {
namespace {

Mesh UnitCube() {
  Mesh mesh;
  mesh.V.resize(8, 3);
  for (int i = 0; i < 8; ++i) mesh.V.row(i) << (i & 1), ((i >> 1) & 1), ((i >> 2) & 1);
  mesh.F.resize(12, 3);
  mesh.F << 0, 2, 1, 1, 2, 3,  // z = 0
      4, 5, 6, 5, 7, 6,        // z = 1
      0, 1, 4, 1, 5, 4,        // y = 0
      2, 6, 3, 3, 6, 7,        // y = 1
      0, 4, 2, 2, 4, 6,        // x = 0
      1, 3, 5, 3, 7, 5;        // x = 1
  return mesh;
}

// Two axis-aligned squares, the first at z = 0 and the second at z = 1 (closer to a camera looking along −z),
// the second smaller so that both are visible.
Mesh TwoSquares() {
  Mesh mesh;
  mesh.V.resize(8, 3);
  mesh.V << -1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0,  //
      -0.5, -0.5, 1, 0.5, -0.5, 1, 0.5, 0.5, 1, -0.5, 0.5, 1;
  mesh.F.resize(4, 3);
  mesh.F << 0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7;
  return mesh;
}

int CountNonBackground(const RgbImage& image) {
  int count = 0;
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      const auto* p = image.at(x, y);
      if (p[0] != 255 || p[1] != 255 || p[2] != 255) ++count;
    }
  }
  return count;
}

TEST(Render, CubeCoversTheImageCentre) {
  RenderOptions options;
  options.width_px = 64;
  options.height_px = 48;
  options.view_direction = {-1, -1, -1};
  for (Projection projection : {Projection::kOrthographic, Projection::kPerspective}) {
    for (Shading shading : {Shading::kFlat, Shading::kSmooth}) {
      options.projection = projection;
      options.shading = shading;
      const RgbImage image = RenderMesh(UnitCube(), options);
      ASSERT_EQ(image.width, 64);
      ASSERT_EQ(image.height, 48);
      EXPECT_GT(CountNonBackground(image), 64 * 48 / 5);
      const auto* centre = image.at(32, 24);
      EXPECT_FALSE(centre[0] == 255 && centre[1] == 255 && centre[2] == 255);
      // The corners stay background (the margin).
      const auto* corner = image.at(0, 0);
      EXPECT_EQ(corner[0], 255);
    }
  }
}

// A 20×20 grid of vertices on the unit square (z = 0), and with `stray` a small triangle far away from it (as a
// depth image's mismatched pixels far behind the scene).
Mesh GridWithStray(bool stray) {
  constexpr int n = 20;
  Mesh mesh;
  mesh.V.resize(n * n + (stray ? 3 : 0), 3);
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) mesh.V.row(y * n + x) << x / (n - 1.0), y / (n - 1.0), 0.0;
  }
  mesh.F.resize(2 * (n - 1) * (n - 1) + (stray ? 1 : 0), 3);
  int f = 0;
  for (int y = 0; y + 1 < n; ++y) {
    for (int x = 0; x + 1 < n; ++x) {
      const int a = y * n + x;
      mesh.F.row(f++) << a, a + 1, a + n + 1;
      mesh.F.row(f++) << a, a + n + 1, a + n;
    }
  }
  if (stray) {
    mesh.V.bottomRows(3) << 40, 30, -5, 41, 30, -5, 40, 31, -5;
    mesh.F.row(f) << n * n, n * n + 1, n * n + 2;
  }
  return mesh;
}

// A direction is a direction at any length: 1e200 overflowed the norm and gave a blank picture, 1e-300 was refused.
TEST(Render, TheViewDirectionsLengthDoesNotMatter) {
  RenderOptions options;
  options.width_px = 64;
  options.height_px = 48;
  options.view_direction = {-1, -1, -1};
  const RgbImage reference = RenderMesh(UnitCube(), options);
  for (const double scale : {1e200, 1e-300}) {
    options.view_direction = Eigen::Vector3d(-1, -1, -1) * scale;
    const RgbImage image = RenderMesh(UnitCube(), options);
    EXPECT_EQ(image.rgb, reference.rgb) << "scale " << scale;
  }
}

TEST(Render, CentralBoxLeavesOutStrayVertices) {
  const Mesh clean = GridWithStray(false), stray = GridWithStray(true);
  const Eigen::AlignedBox3d all = CentralBox(stray, 1.0);
  EXPECT_EQ(all.max(), Eigen::Vector3d(41, 31, 0));
  EXPECT_EQ(all.min(), Eigen::Vector3d(0, 0, -5));
  const Eigen::AlignedBox3d central = CentralBox(stray, 0.98);
  EXPECT_EQ(central.min(), Eigen::Vector3d(0, 0, 0));
  EXPECT_EQ(central.max(), Eigen::Vector3d(1, 1, 0));
  EXPECT_TRUE(CentralBox(Mesh(), 1.0).isEmpty());
  EXPECT_THROW(CentralBox(clean, 0.4), Error);
}

// With a fit_box the view is fitted to the box, whatever else the mesh holds: the grid with a stray triangle
// framed by the grid's box renders exactly as the grid alone (the triangle falls outside the image), and
// without the box the stray triangle shrinks the grid.
TEST(Render, FitBoxFramesEveryMeshTheSame) {
  const Mesh clean = GridWithStray(false), stray = GridWithStray(true);
  RenderOptions options;
  options.width_px = 64;
  options.height_px = 48;
  const RgbImage alone = RenderMesh(clean, options);
  const int covered = CountNonBackground(alone);
  EXPECT_GT(covered, 64 * 48 / 3);
  EXPECT_LT(CountNonBackground(RenderMesh(stray, options)), covered / 10);
  options.fit_box = CentralBox(stray, 0.98);
  EXPECT_EQ(RenderMesh(stray, options).rgb, alone.rgb);
  EXPECT_EQ(RenderMesh(clean, options).rgb, alone.rgb);
}

// A depth image's mesh (pixel (u, v) at depth 2 + 0.01 u, in the camera frame x right, y down, z forward) is
// drawn as its camera saw it; the same mesh upside down, behind the camera, or without pixels is not.
TEST(Render, CameraFrameViewOnlyForMeshesInTheirCamerasFrame) {
  NoisyMesh depth;
  depth.mesh = GridWithStray(false);
  depth.pixel.resize(depth.mesh.num_vertices(), 2);
  for (int v = 0; v < depth.mesh.num_vertices(); ++v) {
    const double u = 19 * depth.mesh.V(v, 0), w = 19 * depth.mesh.V(v, 1), z = 2 + 0.01 * u;
    depth.pixel.row(v) << static_cast<float>(u), static_cast<float>(w);
    depth.mesh.V.row(v) << (u - 10) * z / 500, (w - 10) * z / 500, z;
  }
  RenderOptions options;
  ASSERT_TRUE(SetCameraFrameView(depth, &options));
  EXPECT_EQ(options.view_direction, Eigen::Vector3d(0, 0, 1));
  EXPECT_EQ(options.up, Eigen::Vector3d(0, -1, 0));
  EXPECT_FALSE(options.fit_box.isEmpty());
  EXPECT_GT(CountNonBackground(RenderMesh(depth.mesh, options)), options.width_px * options.height_px / 3);

  NoisyMesh flipped = depth;
  flipped.mesh.V.col(1) *= -1;
  RenderOptions untouched;
  EXPECT_FALSE(SetCameraFrameView(flipped, &untouched));
  EXPECT_EQ(untouched.view_direction, RenderOptions().view_direction);
  NoisyMesh behind = depth;
  behind.mesh.V.col(2) *= -1;
  EXPECT_FALSE(SetCameraFrameView(behind, &untouched));
  NoisyMesh no_pixels;
  no_pixels.mesh = depth.mesh;
  EXPECT_FALSE(SetCameraFrameView(no_pixels, &untouched));
  EXPECT_TRUE(untouched.fit_box.isEmpty());
}

TEST(Render, NearerFaceHidesFartherFace) {
  Mesh mesh = TwoSquares();
  RenderOptions options;
  options.width_px = 100;
  options.height_px = 100;
  options.face_colors.resize(4, 3);
  options.face_colors << 1, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 1;
  for (Projection projection : {Projection::kOrthographic, Projection::kPerspective}) {
    options.projection = projection;
    options.view_direction = {0, 0, -1};  // the blue square (z = 1) is in front
    RgbImage image = RenderMesh(mesh, options);
    EXPECT_EQ(image.at(50, 50)[0], 0);
    EXPECT_GT(image.at(50, 50)[2], 100);
    EXPECT_GT(image.at(10, 50)[0], 100);  // red ring outside the blue square
    options.view_direction = {0, 0, 1};   // from behind: the red square hides the blue one
    image = RenderMesh(mesh, options);
    EXPECT_GT(image.at(50, 50)[0], 100);
    EXPECT_EQ(image.at(50, 50)[2], 0);
  }
}

TEST(Render, CornerNormalsAndDegenerateInput) {
  Mesh mesh = UnitCube();
  RenderOptions options;
  options.width_px = 32;
  options.height_px = 32;
  options.shading = Shading::kSmooth;
  options.corner_normals = Normals::Zero(36, 3);  // zero normals fall back to the face normal
  EXPECT_GT(CountNonBackground(RenderMesh(mesh, options)), 0);
  options.corner_normals.resize(5, 3);
  EXPECT_THROW(RenderMesh(mesh, options), Error);
  // Zero-area faces, NaN vertices and an empty mesh render without error.
  Mesh bad = mesh;
  bad.V.row(7).setConstant(std::nan(""));
  bad.F.row(0) << 0, 0, 1;
  EXPECT_NO_THROW(RenderMesh(bad, RenderOptions{}));
  EXPECT_EQ(CountNonBackground(RenderMesh(Mesh{}, RenderOptions{})), 0);
  bad.F(1, 0) = 99;
  EXPECT_THROW(RenderMesh(bad, RenderOptions{}), Error);
}

TEST(Render, SideBySidePlacesImagesWithGap) {
  RgbImage a(10, 5, 0), b(20, 8, 100);
  const RgbImage out = SideBySide({a, b}, 4);
  EXPECT_EQ(out.width, 34);
  EXPECT_EQ(out.height, 8);
  EXPECT_EQ(out.at(9, 4)[0], 0);
  EXPECT_EQ(out.at(9, 6)[0], 255);   // below the shorter image
  EXPECT_EQ(out.at(12, 0)[0], 255);  // gap
  EXPECT_EQ(out.at(14, 7)[0], 100);
  EXPECT_EQ(SideBySide({}).width, 0);
}

}  // namespace
}  // namespace rangebayes

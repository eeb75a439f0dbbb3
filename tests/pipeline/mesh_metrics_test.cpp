// What `rangebayes eval` computes, on meshes whose answers are known.
#include "pipeline/mesh_metrics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <utility>

#include "core/error.h"

namespace rangebayes {
namespace {

// The unit square in z = height, two triangles.
Mesh Square(double height) {
  Mesh m;
  m.V.resize(4, 3);
  m.V << 0, 0, height, 1, 0, height, 1, 1, height, 0, 1, height;
  m.F.resize(2, 3);
  m.F << 0, 1, 2, 0, 2, 3;
  return m;
}

// A vertex no face uses is not surface: a stray point far away, in either mesh, changed the Hausdorff distance, the
// mean distance and the box's diagonal (85 of an 87-unit diagonal for two equal squares).
TEST(EvaluateMesh, UnusedVerticesAreNotSurface) {
  const auto with_stray = [](Mesh m) {
    m.V.conservativeResize(5, 3);
    m.V.row(4) << 50, 50, 50;
    return m;
  };
  for (const auto& [result, truth] :
       {std::pair<Mesh, Mesh>{with_stray(Square(0.25)), Square(0)}, {Square(0.25), with_stray(Square(0))}}) {
    const SurfaceErrors e = ComputeSurfaceErrors(result, truth);
    EXPECT_DOUBLE_EQ(e.hausdorff, 0.25);
    EXPECT_DOUBLE_EQ(e.mean_distance, 0.25);
    EXPECT_DOUBLE_EQ(e.bbox_diagonal, std::sqrt(2.0));
  }
}

TEST(EvaluateMesh, AParallelCopyIsItsOffsetAwayWithTheSameNormals) {
  const MeshEvaluation e = EvaluateMesh(Square(0.25), Square(0), /*normals=*/true);
  ASSERT_TRUE(e.has_normal_error);
  EXPECT_DOUBLE_EQ(e.mae_deg, 0.0);
  EXPECT_EQ(e.mae_skipped_faces, 0);
  EXPECT_DOUBLE_EQ(e.surface.mean_distance, 0.25);
  EXPECT_DOUBLE_EQ(e.surface.hausdorff, 0.25);
  EXPECT_DOUBLE_EQ(e.surface.ev, 0.25);
  EXPECT_DOUBLE_EQ(e.surface.bbox_diagonal, std::sqrt(2.0));
  EXPECT_EQ(e.faces, 2);
  EXPECT_EQ(e.vertices, 4);
  // The fields of eval's JSON line, in its order; counts marked as such.
  const std::vector<EvaluationField> fields = EvaluationFields(e);
  std::vector<std::string> names;
  for (const EvaluationField& f : fields) names.push_back(f.name);
  EXPECT_EQ(names,
            (std::vector<std::string>{"bbox_diagonal", "ev", "ev_rel_bbox", "faces", "hausdorff", "hausdorff_rel_bbox",
                                      "mae_deg", "mae_skipped_faces", "mean_distance", "vertices"}));
  for (const EvaluationField& f : fields) {
    EXPECT_EQ(f.count, f.name == "faces" || f.name == "vertices" || f.name == "mae_skipped_faces") << f.name;
  }
  EXPECT_FALSE(EvaluateMesh(Square(0.25), Square(0), /*normals=*/false).has_normal_error);
}

// The unit square tilted about the y axis: z = slope · x, both faces' normals turned by atan(slope).
Mesh TiltedSquare(double slope) {
  Mesh m = Square(0);
  for (int v = 0; v < 4; ++v) m.V(v, 2) = slope * m.V(v, 0);
  return m;
}

// Known non-zero answers. Tilting both faces by atan(0.1) = 5.711° gives that angle; tilting one face only
// gives half of it (a mean over faces, not area weighted: both faces have the same area anyway); a face of
// repeated indices is left out and counted. Surfaces: the tilted square's corners lie 0, 0.1, 0.1, 0 above the
// flat one (mean 0.05, largest 0.1); the flat corners lie at most 0.1/√1.01 from the tilted plane; Ev is
// sqrt(Σ_f A Σ_(i∈f) d_i² / (3 · 2A)) = sqrt((0.02 + 0.01) / 6) for faces (0,1,2) and (0,2,3).
TEST(EvaluateMesh, ATiltedCopyHasItsAngleAndDistances) {
  const double tilt_deg = std::atan(0.1) * 180.0 / M_PI;  // 5.7106°
  const MeshEvaluation e = EvaluateMesh(TiltedSquare(0.1), Square(0), /*normals=*/true);
  EXPECT_NEAR(e.mae_deg, tilt_deg, 1e-9);
  EXPECT_EQ(e.mae_skipped_faces, 0);
  EXPECT_NEAR(e.surface.mean_distance, 0.05, 1e-12);
  EXPECT_NEAR(e.surface.hausdorff, 0.1, 1e-12);
  EXPECT_NEAR(e.surface.ev, std::sqrt(0.03 / 6.0), 1e-12);
  EXPECT_GT(e.surface.hausdorff, 1.5 * e.surface.mean_distance);

  // One face tilted (corner 1 is only in face (0, 1, 2)): raised by h its normal turns by atan(h·√2).
  Mesh one = Square(0);
  one.V(1, 2) = 0.1 / std::sqrt(2.0);
  int skipped = -1;
  EXPECT_NEAR(MeanAngularErrorDeg(one, Square(0), &skipped), tilt_deg / 2, 1e-9);
  EXPECT_EQ(skipped, 0);

  // A degenerate third face in both meshes: skipped and counted, the mean over the other two unchanged.
  Mesh result = TiltedSquare(0.1), truth = Square(0);
  for (Mesh* m : {&result, &truth}) {
    m->F.conservativeResize(3, 3);
    m->F.row(2) << 0, 0, 1;
  }
  const MeshEvaluation d = EvaluateMesh(result, truth, /*normals=*/true);
  EXPECT_NEAR(d.mae_deg, tilt_deg, 1e-9);
  EXPECT_EQ(d.mae_skipped_faces, 1);
}

TEST(EvaluateMesh, MeshesItCannotCompareAreRefused) {
  Mesh other = Square(0);
  other.F.row(1) << 0, 3, 2;  // same vertices, another face
  EXPECT_FALSE(SameConnectivity(other, Square(0)));
  EXPECT_THROW(EvaluateMesh(other, Square(0), /*normals=*/true), Error);
  EXPECT_NO_THROW(EvaluateMesh(other, Square(0), /*normals=*/false));
  Mesh points = Square(0);
  points.F.resize(0, 3);
  EXPECT_THROW(EvaluateMesh(points, Square(0), false), Error);
  EXPECT_THROW(EvaluateMesh(Square(0), points, false), Error);
  Mesh broken = Square(0);
  broken.V(2, 0) = std::numeric_limits<double>::quiet_NaN();
  try {
    EvaluateMesh(broken, Square(0), false);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("the result: 1 of 4 vertices have non-finite coordinates"), std::string::npos)
        << e.what();
  }
  EXPECT_THROW(EvaluateMesh(Square(0), broken, false), Error);
}

}  // namespace
}  // namespace rangebayes

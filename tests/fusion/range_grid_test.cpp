#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>

#include "core/error.h"
#include "core/mesh_io.h"
#include "fusion/scan.h"
#include "tests/temp_dir.h"

namespace rangebayes {
namespace {

// A 3×2 grid with five vertices on the plane z = 1 (cell (2, 1) empty), as the Stanford scans store it.
std::string GridPly(const std::string& cells, int rows = 2) {
  return "ply\nformat ascii 1.0\nobj_info num_cols 3\nobj_info num_rows " + std::to_string(rows) +
         "\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\n"
         "element range_grid " + std::to_string(3 * rows) + "\nproperty list uchar int vertex_indices\nend_header\n"
         "0 0 1\n0.001 0 1\n0.002 0 1\n0 0.001 1\n0.001 0.001 1\n" + cells;
}

TEST(RangeGrid, ReadsCellsRowByRow) {
  const std::string path = WriteTempFile("grid.ply", GridPly("1 0\n1 1\n1 2\n1 3\n1 4\n0\n"));
  const RangeGridScan scan = ReadRangeGridScan(path);
  ASSERT_TRUE(scan.has_grid());
  EXPECT_EQ(scan.width, 3);
  EXPECT_EQ(scan.height, 2);
  ASSERT_EQ(scan.cell_vertex.size(), 6u);
  EXPECT_EQ(scan.cell_vertex[4], 4);
  EXPECT_EQ(scan.cell_vertex[5], -1);
  EXPECT_EQ(scan.mesh.mesh.num_vertices(), 5);
  // A plain mesh reader still skips the grid.
  EXPECT_EQ(ReadMesh(path).num_vertices(), 5);
}

TEST(RangeGrid, TriangulatesAsAnOrganizedGrid) {
  const RangeGridScan grid = ReadRangeGridScan(WriteTempFile("grid2.ply", GridPly("1 0\n1 1\n1 2\n1 3\n1 4\n0\n")));
  RangeGridScanSummary summary;
  const Scan scan = MakeRangeGridScan(grid, "grid2.ply", {}, &summary);
  // Block (0,0) has four vertices: two triangles; block (1,0) three: one triangle.
  EXPECT_EQ(scan.noisy.mesh.num_faces(), 3);
  EXPECT_EQ(summary.cut_edges, 0);
  ASSERT_TRUE(scan.noisy.has_covariance());
  for (int i = 0; i < 5; ++i) {
    // Rows have no extent along a ray here: rays along −z, normals facing the sensor (+z).
    EXPECT_NEAR(scan.ray(i, 2), -1.0, 1e-12);
    EXPECT_NEAR(scan.normal(i, 2), 1.0, 1e-9);
    const Eigen::Vector3d r = scan.ray.row(i);
    EXPECT_NEAR(r.dot(scan.noisy.covariance[i] * r), 4e-8, 1e-15);  // σ_range² default (0.2 mm)²
  }
}

TEST(RangeGrid, CutsDepthJumps) {
  // The last vertex 5 cm behind the plane: every edge to it is cut.
  std::string text = GridPly("1 0\n1 1\n1 2\n1 3\n1 4\n0\n");
  text.replace(text.find("0.001 0.001 1\n"), 14, "0.001 0.001 0.95\n");
  const Scan scan = MakeRangeGridScan(ReadRangeGridScan(WriteTempFile("jump.ply", text)), "jump.ply");
  EXPECT_EQ(scan.noisy.mesh.num_faces(), 1);  // only (0, 1, 3) remains
}

TEST(RangeGrid, StanfordPiecesReadWithFanRays) {
  const std::string path = std::string(RB_SOURCE_DIR) + "/tests/data/scans/bun000_piece.ply";
  RangeGridScanSummary summary;
  const Scan scan = ReadScan(path, {}, &summary);
  EXPECT_EQ(summary.ray_model, "fan");
  EXPECT_LT(summary.row_fit_rms, 3e-5);  // rows lie on one laser ray each (RMS 3–14 µm on the full scan)
  EXPECT_GT(scan.noisy.mesh.num_faces(), scan.num_vertices());
  EXPECT_NEAR(scan.mean_edge, 8e-4, 2e-4);  // 0.5 mm motion steps, interlaced rows, plus diagonals
}

// The same scan read as a mesh with covariances (what `convert` writes of it and Python's read_mesh returns): no
// sensor position is known, and the Stanford scanner's origin lies inside the bunny. The rays come from the
// covariances' long axes, pointed as the faces say; the rays from the origin flipped normals and fused the two
// bunny scans with 98 components instead of 39.
TEST(RangeGrid, AGridReadAsAMeshKeepsItsRays) {
  const Scan grid = ReadScan(std::string(RB_SOURCE_DIR) + "/tests/data/scans/bun000_piece.ply");
  const Scan mesh = MakeScanFromMesh(grid.noisy, "piece");
  ASSERT_EQ(mesh.num_vertices(), grid.num_vertices());
  int rays = 0, normals = 0;
  for (int i = 0; i < grid.num_vertices(); ++i) {
    rays += grid.ray.row(i).dot(mesh.ray.row(i)) > 0.99 ? 1 : 0;
    normals += grid.normal.row(i).dot(mesh.normal.row(i)) > 0.99 ? 1 : 0;
  }
  EXPECT_GT(rays, 0.99 * grid.num_vertices());
  EXPECT_GT(normals, 0.99 * grid.num_vertices());
  EXPECT_EQ(mesh.noisy.mesh.F, grid.noisy.mesh.F);  // not turned over
}

TEST(RangeGrid, FacesInTheFileWinOverItsGridInBothReaders) {
  // The grid alone would give three triangles; the file lists one face of its own.
  std::string text = GridPly("1 0\n1 1\n1 2\n1 3\n1 4\n0\n");
  text.replace(text.find("end_header"), 10, "element face 1\nproperty list uchar int vertex_indices\nend_header");
  text += "3 0 1 4\n";
  const std::string path = WriteTempFile("grid_faces.ply", text);
  EXPECT_EQ(ReadMeshOrRangeGrid(path).mesh.num_faces(), 1);
  EXPECT_EQ(ReadScan(path).noisy.mesh.num_faces(), 1);
  // Without the face list both triangulate the grid.
  const std::string grid_only = WriteTempFile("grid_only.ply", GridPly("1 0\n1 1\n1 2\n1 3\n1 4\n0\n"));
  EXPECT_EQ(ReadMeshOrRangeGrid(grid_only).mesh.num_faces(), 3);
  EXPECT_EQ(ReadScan(grid_only).noisy.mesh.num_faces(), 3);
}

TEST(RangeGrid, BadGridsNameTheFileAndCell) {
  const auto message = [](const std::string& name, const std::string& text) {
    try {
      ReadRangeGridScan(WriteTempFile(name, text));
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message("two.ply", GridPly("1 0\n2 1 2\n1 2\n1 3\n1 4\n0\n")).find("cell 1 lists 2 vertices"),
            std::string::npos);
  EXPECT_NE(message("range.ply", GridPly("1 0\n1 9\n1 2\n1 3\n1 4\n0\n")).find("names vertex 9"), std::string::npos);
  std::string no_size = GridPly("1 0\n1 1\n1 2\n1 3\n1 4\n0\n");
  no_size.replace(no_size.find("obj_info num_cols 3\n"), 20, "");
  EXPECT_NE(message("nosize.ply", no_size).find("without its size"), std::string::npos);
  std::string count = GridPly("1 0\n1 1\n1 2\n1 3\n1 4\n");
  count.replace(count.find("range_grid 6"), 12, "range_grid 5");
  EXPECT_NE(message("count.ply", count).find("count.ply: 'range_grid' has 5 cells but num_cols x num_rows is 3 x 2"),
            std::string::npos);
  // A size whose product wraps in 64 bits to the cell count (3 × 6148914691236517206 = 2 mod 2^64) was taken for
  // a grid of 3 × 1431655766 cells over 2 (a segfault reading them).
  std::string wrapped = GridPly("1 0\n1 1\n");
  wrapped.replace(wrapped.find("obj_info num_rows 2"), 19, "obj_info num_rows 6148914691236517206");
  wrapped.replace(wrapped.find("range_grid 6"), 12, "range_grid 2");
  EXPECT_NE(message("wrapped.ply", wrapped).find("is too large"), std::string::npos) << message("wrapped.ply", wrapped);
}

// A noise level in the wrong units (as large as the scan, or below its coordinates' precision) is refused by name
// instead of failing the registration later with a misleading line about the initial poses.
TEST(RangeGrid, NoiseInTheWrongUnitsIsRefused) {
  const std::string path = std::string(RB_SOURCE_DIR) + "/tests/data/scans/bun000_piece.ply";
  // The piece's diagonal is 0.097 m; the bounds are 0.25 and 1e-6 of it. 0.05 and 5e-8 were let through by the
  // old bounds (1 and 1e-7), as millimetres given for metres and the reverse were on the whole bunny scans.
  for (const double sigma : {1.0, 0.05, 1e-12, 5e-8}) {
    RangeGridScanOptions options;
    options.sigma_range = sigma;
    try {
      ReadScan(path, options);
      FAIL() << "no error for sigma_range " << sigma;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("bun000_piece.ply: sigma_range"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("give the noise in the scan's units"), std::string::npos) << e.what();
    }
  }
  RangeGridScanOptions options;
  options.sigma_lateral = 10.0;
  EXPECT_THROW(ReadScan(path, options), Error);
}

TEST(RangeGrid, EmptyScanIsAnError) {
  const std::string path = WriteTempFile("empty.ply", GridPly("0\n0\n0\n0\n0\n0\n"));
  try {
    ReadScan(path);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("empty.ply: empty scan"), std::string::npos) << e.what();
  }
}

// A scan with non-finite vertices is refused, saying how many and which first (it said "not all finite").
TEST(RangeGrid, NonFiniteVerticesAreCountedAndNamed) {
  NoisyMesh mesh;
  mesh.mesh.V.resize(4, 3);
  mesh.mesh.V << 0, 0, 0, 1, 0, 0, 0, 1, 0, std::nan(""), 0, 0;
  mesh.mesh.F.resize(1, 3);
  mesh.mesh.F << 0, 1, 2;
  try {
    MakeScanFromMesh(mesh, "nan.ply");
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("nan.ply: 1 of 4 vertices have non-finite coordinates (the first: vertex 3 "),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace rangebayes

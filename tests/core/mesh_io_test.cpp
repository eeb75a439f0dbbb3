#include "core/mesh_io.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <random>
#include <string>

#include "core/error.h"
#include "tests/temp_dir.h"
#include "tests/test_meshes.h"

namespace rangebayes {
namespace {

namespace fs = std::filesystem;

// A fresh folder per test (tests/temp_dir.h), removed afterwards.
class MeshIoTest : public ::testing::Test {
 protected:
  void SetUp() override {
    temp_ = std::make_unique<TempDir>(std::string("mesh_io_") +
                                      ::testing::UnitTest::GetInstance()->current_test_info()->name());
    dir_ = temp_->path();
  }
  void TearDown() override { temp_.reset(); }

  std::string Path(const std::string& name) const { return (dir_ / name).string(); }

  std::string WriteBytes(const std::string& name, const std::string& bytes) const {
    const std::string path = Path(name);
    std::ofstream out(path, std::ios::binary);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    return path;
  }

  std::unique_ptr<TempDir> temp_;
  fs::path dir_;
};

// Random positions with awkward doubles (not representable in short decimals) and a shuffled face list.
Mesh RandomMesh(int num_vertices, int num_faces, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> coord(-1e3, 1e3);
  std::uniform_int_distribution<int> index(0, num_vertices - 1);
  Mesh mesh;
  mesh.V.resize(num_vertices, 3);
  for (int i = 0; i < num_vertices; ++i) mesh.V.row(i) << coord(rng), coord(rng) * 1e-7, coord(rng) / 3.0;
  mesh.F.resize(num_faces, 3);
  for (int f = 0; f < num_faces; ++f) mesh.F.row(f) << index(rng), index(rng), index(rng);
  return mesh;
}

using testing::Tetrahedron;

// Eigen's == asserts equal sizes only in debug builds: check them first.
template <typename A, typename B>
bool Same(const A& a, const B& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() && a == b;
}

void ExpectSameMesh(const Mesh& a, const Mesh& b) {
  ASSERT_EQ(a.V.rows(), b.V.rows());
  ASSERT_EQ(a.F.rows(), b.F.rows());
  EXPECT_TRUE(a.V == b.V) << "vertex positions differ";
  EXPECT_TRUE(a.F == b.F) << "faces differ";
}

TEST_F(MeshIoTest, FormatFromPath) {
  EXPECT_EQ(MeshFormatFromPath("a/b.PLY"), MeshFormat::kPly);
  EXPECT_EQ(MeshFormatFromPath("x.obj"), MeshFormat::kObj);
  EXPECT_EQ(MeshFormatFromPath("x.Off"), MeshFormat::kOff);
  EXPECT_THROW(MeshFormatFromPath("x.stl"), Error);
  EXPECT_THROW(MeshFormatFromPath("dir.ply/x"), Error);
}

// Every format and encoding keeps vertex order, faces and every bit of each coordinate.
TEST_F(MeshIoTest, RoundTripEveryFormatIsExact) {
  const Mesh mesh = RandomMesh(500, 1000, 7);
  struct Case {
    std::string file;
    PlyEncoding encoding;
  };
  const Case cases[] = {{"a.ply", PlyEncoding::kBinaryLittleEndian},
                        {"b.ply", PlyEncoding::kBinaryBigEndian},
                        {"c.ply", PlyEncoding::kAscii},
                        {"d.obj", PlyEncoding::kBinaryLittleEndian},
                        {"e.off", PlyEncoding::kBinaryLittleEndian}};
  for (const Case& c : cases) {
    SCOPED_TRACE(c.file);
    MeshWriteOptions options;
    options.ply_encoding = c.encoding;
    WriteMesh(mesh, Path(c.file), options);
    MeshReadSummary summary;
    const Mesh back = ReadMesh(Path(c.file), &summary);
    ExpectSameMesh(mesh, back);
    EXPECT_EQ(back.N.rows(), 0);
    EXPECT_EQ(summary.polygons_triangulated, 0);
  }
}

TEST_F(MeshIoTest, RoundTripKeepsVertexNormals) {
  Mesh mesh = RandomMesh(50, 80, 3);
  mesh.N = RandomMesh(50, 1, 4).V;
  for (const std::string file : {"n.ply", "n.obj", "n.off"}) {
    SCOPED_TRACE(file);
    WriteMesh(mesh, Path(file));
    const Mesh back = ReadMesh(Path(file));
    ExpectSameMesh(mesh, back);
    EXPECT_TRUE(Same(back.N, mesh.N));
  }
  MeshWriteOptions no_normals;
  no_normals.write_vertex_normals = false;
  WriteMesh(mesh, Path("plain.obj"), no_normals);
  EXPECT_EQ(ReadMesh(Path("plain.obj")).N.rows(), 0);
}

TEST_F(MeshIoTest, NoisyMeshRoundTripKeepsCovarianceAndPixels) {
  NoisyMesh noisy;
  noisy.mesh = RandomMesh(30, 40, 11);
  std::mt19937 rng(5);
  std::normal_distribution<double> normal(0, 1);
  for (int i = 0; i < 30; ++i) {
    Eigen::Matrix3d a;
    for (int k = 0; k < 9; ++k) a(k / 3, k % 3) = normal(rng);
    const Eigen::Matrix3d c = a * a.transpose() * 1e-6;
    noisy.covariance.push_back(0.5 * (c + c.transpose()));  // exactly symmetric, as the file stores 6 values
  }
  noisy.pixel.resize(30, 2);
  for (int i = 0; i < 30; ++i) noisy.pixel.row(i) << static_cast<float>(i) + 0.25f, static_cast<float>(2 * i) / 3.f;
  for (const PlyEncoding encoding : {PlyEncoding::kBinaryLittleEndian, PlyEncoding::kBinaryBigEndian, PlyEncoding::kAscii}) {
    MeshWriteOptions options;
    options.ply_encoding = encoding;
    WriteNoisyMesh(noisy, Path("noisy.ply"), options);
    const NoisyMesh back = ReadNoisyMesh(Path("noisy.ply"));
    ExpectSameMesh(noisy.mesh, back.mesh);
    ASSERT_TRUE(back.has_covariance());
    for (int i = 0; i < 30; ++i) EXPECT_TRUE(back.covariance[i] == noisy.covariance[i]) << i;
    EXPECT_TRUE(Same(back.pixel, noisy.pixel));
  }
  // A plain mesh read as noisy has no covariance; covariance cannot go to OBJ.
  WriteMesh(noisy.mesh, Path("plain.ply"));
  EXPECT_FALSE(ReadNoisyMesh(Path("plain.ply")).has_covariance());
  EXPECT_THROW(WriteNoisyMesh(noisy, Path("noisy.obj")), Error);
}

TEST_F(MeshIoTest, NonFiniteCoordinatesAreReadBack) {
  Mesh mesh = Tetrahedron();
  mesh.V(1, 0) = std::numeric_limits<double>::quiet_NaN();
  mesh.V(2, 1) = std::numeric_limits<double>::infinity();
  for (const std::string file : {"nan.ply", "nan.obj", "nan.off"}) {
    MeshWriteOptions ascii;
    ascii.ply_encoding = PlyEncoding::kAscii;
    WriteMesh(mesh, Path(file), ascii);
    const Mesh back = ReadMesh(Path(file));
    EXPECT_TRUE(std::isnan(back.V(1, 0))) << file;
    EXPECT_EQ(back.V(2, 1), std::numeric_limits<double>::infinity()) << file;
  }
}

TEST_F(MeshIoTest, ObjCornerForms) {
  const std::string path = WriteBytes("forms.obj",
                                      "# comment\n"
                                      "mtllib x.mtl\n"
                                      "o thing\n"
                                      "v 0 0 0\n"
                                      "v 1 0 0 1.0\n"  // w is ignored
                                      "v 1 1 0 0.5 0.5 0.5\n"
                                      "v 0 1 0\r\n"
                                      "vt 0 0\nvt 1 0\nvt 1 1\n"
                                      "vn 0 0 1\n"
                                      "g group\n"
                                      "usemtl m\n"
                                      "s 1\n"
                                      "f 1/1/1 2/2/1 3/3/1\n"
                                      "f -4//-1 -2//-1 -1//-1\n"
                                      "f 1/1 3/3 4/2\r\n"
                                      "f 1 2 3 4\n");
  MeshReadSummary summary;
  const Mesh mesh = ReadMesh(path, &summary);
  ASSERT_EQ(mesh.num_vertices(), 4);
  ASSERT_EQ(mesh.num_faces(), 5);
  Faces expected(5, 3);
  expected << 0, 1, 2, 0, 2, 3, 0, 2, 3, 0, 1, 2, 0, 2, 3;
  EXPECT_TRUE(Same(mesh.F, expected)) << mesh.F;
  EXPECT_EQ(summary.polygons_triangulated, 1);
  EXPECT_EQ(mesh.V(2, 1), 1.0);
  // Vertex 1 gets its normal from faces; all four have one.
  ASSERT_EQ(mesh.N.rows(), 4);
  EXPECT_EQ(mesh.N(1, 2), 1.0);
}

TEST_F(MeshIoTest, ObjCornerNormalsWriteAndAverage) {
  const Mesh mesh = Tetrahedron();
  MeshWriteOptions options;
  // Flat shading: one normal per face, so each vertex sees three different normals.
  options.corner_normals.normals.resize(4, 3);
  options.corner_normals.normals << 0, 0, -1, 0, -1, 0, -1, 0, 0, 1, 1, 1;
  options.corner_normals.normals.row(3).normalize();
  options.corner_normals.normal_index.resize(4, 3);
  for (int f = 0; f < 4; ++f) options.corner_normals.normal_index.row(f).setConstant(f);
  WriteMesh(mesh, Path("flat.obj"), options);
  MeshReadSummary summary;
  const Mesh back = ReadMesh(Path("flat.obj"), &summary);
  ExpectSameMesh(mesh, back);
  ASSERT_EQ(back.N.rows(), 4);
  // Vertex 0 is in faces 0, 1, 2: the mean of −z, −y, −x.
  EXPECT_NEAR(back.N(0, 0), -1 / std::sqrt(3.0), 1e-12);
  EXPECT_NEAR(back.N.row(3).norm(), 1.0, 1e-12);
  // PLY stores them as a face property that readers skip.
  WriteMesh(mesh, Path("flat.ply"), options);
  ExpectSameMesh(mesh, ReadMesh(Path("flat.ply")));
}

TEST_F(MeshIoTest, PolygonMeshesAreFanTriangulated) {
  Vertices V(6, 3);
  V << 0, 0, 0, 1, 0, 0, 2, 0, 0, 2, 1, 0, 1, 1, 0, 0, 1, 0;
  const std::vector<std::vector<int>> polygons = {{0, 1, 4, 5}, {1, 2, 3, 4}, {0, 2, 3}};
  for (const std::string file : {"poly.ply", "poly.obj", "poly.off"}) {
    SCOPED_TRACE(file);
    WritePolygonMesh(V, polygons, Path(file));
    MeshReadSummary summary;
    const Mesh back = ReadMesh(Path(file), &summary);
    EXPECT_TRUE(Same(back.V, V));
    Faces expected(5, 3);
    expected << 0, 1, 4, 0, 4, 5, 1, 2, 3, 1, 3, 4, 0, 2, 3;
    EXPECT_TRUE(Same(back.F, expected)) << back.F;
    EXPECT_EQ(summary.polygons_triangulated, 2);
    EXPECT_FALSE(summary.notices.empty());
  }
  // A polygon of 300 vertices needs an int count in PLY.
  Vertices ring(300, 3);
  std::vector<int> big;
  for (int i = 0; i < 300; ++i) {
    ring.row(i) << std::cos(i * 0.02), std::sin(i * 0.02), 0;
    big.push_back(i);
  }
  WritePolygonMesh(ring, {big}, Path("ring.ply"));
  EXPECT_EQ(ReadMesh(Path("ring.ply")).num_faces(), 298);
  EXPECT_THROW(WritePolygonMesh(V, {{0, 1}}, Path("bad.obj")), Error);
  EXPECT_THROW(WritePolygonMesh(V, {{0, 1, 6}}, Path("bad.obj")), Error);
}

// A fan from a corner next to a reflex one folds a concave polygon over itself (a triangle of the wrong
// orientation, the area counted twice): such polygons are ear-clipped in their plane instead, into as many
// triangles, all of the polygon's orientation and together of its area; a convex one keeps its fan.
TEST_F(MeshIoTest, ConcavePolygonsAreTriangulatedInTheirPlane) {
  // An L of area 3 in the plane z = 0, listed counter-clockwise from (2, 1), then tilted and moved.
  const double l_shape[6][2] = {{2, 1}, {1, 1}, {1, 2}, {0, 2}, {0, 0}, {2, 0}};
  const Eigen::Matrix3d tilt = (Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized())).toRotationMatrix();
  const double square[2][2] = {{3, 0}, {3, 1}};  // with (2, 0) and (2, 1): a convex quad beside it
  Vertices V(8, 3);
  for (int i = 0; i < 8; ++i) {
    const double* p = i < 6 ? l_shape[i] : square[i - 6];
    V.row(i) = (tilt * Eigen::Vector3d(p[0], p[1], 0) + Eigen::Vector3d(5, -2, 1)).transpose();
  }
  const Eigen::Vector3d up = tilt * Eigen::Vector3d::UnitZ();
  const std::vector<std::vector<int>> polygons = {{0, 1, 2, 3, 4, 5}, {5, 6, 7, 0}};
  for (const std::string file : {"l.ply", "l.obj", "l.off"}) {
    SCOPED_TRACE(file);
    WritePolygonMesh(V, polygons, Path(file));
    MeshReadSummary summary;
    const Mesh back = ReadMesh(Path(file), &summary);
    ASSERT_EQ(back.num_faces(), 6);
    double area = 0;
    for (int f = 0; f < 4; ++f) {
      const Eigen::Vector3d a = back.V.row(back.F(f, 0)), b = back.V.row(back.F(f, 1)), c = back.V.row(back.F(f, 2));
      const Eigen::Vector3d n = (b - a).cross(c - a);
      EXPECT_GT(n.dot(up), 1e-9) << "triangle " << f << " is folded or flat";
      area += 0.5 * n.norm();
    }
    EXPECT_NEAR(area, 3.0, 1e-12);
    // The convex quad keeps its fan (the reader's output unchanged for such files).
    EXPECT_EQ(back.F.row(4), Eigen::RowVector3i(5, 6, 7));
    EXPECT_EQ(back.F.row(5), Eigen::RowVector3i(5, 7, 0));
    EXPECT_EQ(summary.polygons_triangulated, 2);
    ASSERT_FALSE(summary.notices.empty());
    EXPECT_NE(summary.notices[0].find("(1 concave ones by ear clipping in their plane"), std::string::npos)
        << summary.notices[0];
  }
  // An OBJ may name its vertices after the face that uses them: the polygon is decided once they are read.
  std::string forward = "f 1 2 3 4 5 6\n";
  for (int i = 0; i < 6; ++i) forward += StrCat("v ", l_shape[i][0], " ", l_shape[i][1], " 0\n");
  MeshReadSummary summary;
  const Mesh back = ReadMesh(WriteBytes("forward.obj", forward), &summary);
  ASSERT_EQ(back.num_faces(), 4);
  for (int f = 0; f < 4; ++f) {
    const Eigen::Vector3d a = back.V.row(back.F(f, 0)), b = back.V.row(back.F(f, 1)), c = back.V.row(back.F(f, 2));
    EXPECT_GT((b - a).cross(c - a).z(), 1e-9) << "triangle " << f << " is folded or flat";
  }
  EXPECT_NE(summary.notices[0].find("(1 concave ones"), std::string::npos) << summary.notices[0];
}

// What OBJ and OFF readers leave out is said (PLY names the properties it skips); a comment may end an OBJ face.
TEST_F(MeshIoTest, ObjAndOffSayWhatTheyLeaveOut) {
  MeshReadSummary obj;
  const Mesh from_obj = ReadMesh(WriteBytes("c.obj",
                                            "mtllib m.mtl\nv 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\n"
                                            "vt 0 0\nusemtl red\nf 1/1 2/1 3/1 # the only face\n"),
                                 &obj);
  EXPECT_EQ(from_obj.num_faces(), 1);
  const auto has = [](const MeshReadSummary& s, const std::string& text) {
    return std::any_of(s.notices.begin(), s.notices.end(),
                       [&text](const std::string& n) { return n.find(text) != std::string::npos; });
  };
  EXPECT_TRUE(has(obj, "ignored the values after x y z (colours or w) of 3 vertices"));
  EXPECT_TRUE(has(obj, "ignored 1 texture coordinates (vt)"));
  EXPECT_TRUE(has(obj, "ignored the materials (2 usemtl/mtllib statements)"));
  MeshReadSummary off;
  const Mesh from_off = ReadMesh(WriteBytes("c.off",
                                            "COFF\n3 1 0\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n0 1 0 0 0 255 255\n"
                                            "3 0 1 2 200 200 200\n"),
                                 &off);
  EXPECT_EQ(from_off.num_faces(), 1);
  EXPECT_TRUE(has(off, "ignored the values after the position (colours, texture coordinates) of 3 vertices"));
  EXPECT_TRUE(has(off, "ignored the colours of 1 faces"));
  MeshReadSummary plain;
  ReadMesh(WriteBytes("p.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"), &plain);
  EXPECT_TRUE(plain.notices.empty());
}

// Triangle strips (element tristrips, -1 between strips): every other triangle's first two corners swapped so
// that all keep the strip's orientation; a strip's degenerate join triangles are left out.
TEST_F(MeshIoTest, PlyTriangleStripsAreRead) {
  const std::string path =
      WriteBytes("strips.ply",
                 "ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\nproperty float y\nproperty float z\n"
                 "element tristrips 1\nproperty list int int vertex_indices\nend_header\n"
                 "0 0 0\n0 1 0\n1 0 0\n1 1 0\n2 0 0\n5 5 5\n"
                 "9 0 1 2 3 4 4 -1 3 4\n");
  MeshReadSummary summary;
  const Mesh mesh = ReadMesh(path, &summary);
  Faces expected(3, 3);
  expected << 0, 1, 2, 2, 1, 3, 2, 3, 4;
  EXPECT_TRUE(Same(mesh.F, expected)) << mesh.F;
  for (int f = 0; f < 3; ++f) {  // one orientation: every normal along -z
    const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)), b = mesh.V.row(mesh.F(f, 1)), c = mesh.V.row(mesh.F(f, 2));
    EXPECT_LT((b - a).cross(c - a).z(), 0) << f;
  }
  ASSERT_EQ(summary.notices.size(), 1u);
  EXPECT_EQ(summary.notices[0], "read 3 triangles from 1 triangle strips ('tristrips')");
}

TEST_F(MeshIoTest, PlyVariants) {
  // Float coordinates, uint list counts with short indices, extra properties and elements to skip, and a
  // face element before the vertices.
  const std::string header =
      "ply\r\n"
      "format ascii 1.0\r\n"
      "comment made by hand\r\n"
      "element material 1\r\n"
      "property list uchar float weights\r\n"
      "property uchar red\r\n"
      "element face 2\r\n"
      "property uchar flags\r\n"
      "property list uint ushort vertex_index\r\n"
      "element vertex 4\r\n"
      "property float x\r\n"
      "property uchar red\r\n"
      "property float y\r\n"
      "property float z\r\n"
      "end_header\r\n";
  const std::string path = WriteBytes("variant.ply", header +
                                                         "2 0.5 0.25 7\r\n"
                                                         "1 3 0 1 2\r\n"
                                                         "0 4 0 2 3 1\r\n"
                                                         "0 9 0 0\n1 9 0 0\n1 9 1 0\n0.5 9 1 0.5\n");
  MeshReadSummary summary;
  const Mesh mesh = ReadMesh(path, &summary);
  ASSERT_EQ(mesh.num_vertices(), 4);
  ASSERT_EQ(mesh.num_faces(), 3);
  EXPECT_EQ(mesh.V(3, 0), 0.5);
  EXPECT_EQ(mesh.V(3, 2), 0.5);
  Faces expected(3, 3);
  expected << 0, 1, 2, 0, 2, 3, 0, 3, 1;
  EXPECT_TRUE(Same(mesh.F, expected)) << mesh.F;
  EXPECT_EQ(summary.polygons_triangulated, 1);
}

// A binary big-endian file with float coordinates and int16/uint32 list types, assembled byte by byte.
TEST_F(MeshIoTest, PlyBinaryBigEndianFloat) {
  std::string bytes =
      "ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nelement face 1\nproperty list short uint vertex_indices\nend_header\n";
  auto put32 = [&bytes](uint32_t u) {
    for (int s = 24; s >= 0; s -= 8) bytes.push_back(static_cast<char>((u >> s) & 0xff));
  };
  auto put_float = [&put32](float f) {
    uint32_t u;
    std::memcpy(&u, &f, 4);
    put32(u);
  };
  const float coords[9] = {0.1f, 0.2f, 0.3f, 1, 0, 0, 0, 1, -2.5f};
  for (const float c : coords) put_float(c);
  bytes.push_back(0);
  bytes.push_back(3);
  put32(2);
  put32(0);
  put32(1);
  const Mesh mesh = ReadMesh(WriteBytes("be.ply", bytes));
  ASSERT_EQ(mesh.num_vertices(), 3);
  EXPECT_EQ(mesh.V(0, 0), static_cast<double>(0.1f));
  EXPECT_EQ(mesh.V(2, 2), -2.5);
  ASSERT_EQ(mesh.num_faces(), 1);
  EXPECT_EQ(mesh.F(0, 0), 2);
  EXPECT_EQ(mesh.F(0, 2), 1);
}

TEST_F(MeshIoTest, OffVariants) {
  const std::string path = WriteBytes("v.off",
                                      "# leading comment\n"
                                      "NOFF 4 2 0\n"
                                      "0 0 0 0 0 1\n"
                                      "# between vertices\n"
                                      "1 0 0 0 0 1\n"
                                      "1 1 0  0 0 1\n"
                                      "0 1 0 0 0 1\n"
                                      "3 0 1 2 255 0 0\n"
                                      "3 0 2 3\n");
  const Mesh mesh = ReadMesh(path);
  EXPECT_EQ(mesh.num_vertices(), 4);
  EXPECT_EQ(mesh.num_faces(), 2);
  ASSERT_EQ(mesh.N.rows(), 4);
  EXPECT_EQ(mesh.N(2, 2), 1.0);
  const std::string colour = WriteBytes("c.off", "COFF\n3 1 0\n0 0 0 1 1 1 1\n1 0 0 1 1 1 1\n0 1 0 1 1 1 1\n3 0 1 2\n");
  EXPECT_EQ(ReadMesh(colour).num_faces(), 1);
}

TEST_F(MeshIoTest, BundledObjReads) {
  const Mesh angel = ReadMesh("tests/data/meshes/real_angel_scan.obj");
  EXPECT_EQ(angel.num_vertices(), 24566);
  EXPECT_EQ(angel.num_faces(), 48090);
  EXPECT_EQ(angel.N.rows(), 0);
  const Mesh block = ReadMesh("tests/data/meshes/block_gt.obj");
  EXPECT_EQ(block.num_vertices(), 8771);
  EXPECT_EQ(block.N.rows(), 8771);
  // Converting and reading back is exact.
  WriteMesh(block, Path("block.ply"));
  const Mesh back = ReadMesh(Path("block.ply"));
  ExpectSameMesh(block, back);
  EXPECT_TRUE(Same(back.N, block.N));
}

TEST_F(MeshIoTest, WriterRejectsInconsistentMeshes) {
  Mesh mesh = Tetrahedron();
  mesh.F(2, 1) = 4;
  EXPECT_THROW(WriteMesh(mesh, Path("bad.ply")), Error);
  mesh = Tetrahedron();
  mesh.N.resize(2, 3);
  EXPECT_THROW(WriteMesh(mesh, Path("bad.ply")), Error);
  EXPECT_THROW(WriteMesh(Tetrahedron(), Path("bad.stl")), Error);
  EXPECT_THROW(WriteMesh(Tetrahedron(), Path("no/such/dir/x.ply")), Error);
}

}  // namespace
}  // namespace rangebayes

// Malformed mesh files: every one must give one Error line naming the file, never a crash or a huge
// allocation.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <memory>
#include <random>
#include <string>

#include "core/error.h"
#include "core/mesh_io.h"
#include "tests/temp_dir.h"

namespace rangebayes {
namespace {

namespace fs = std::filesystem;

class MalformedMeshTest : public ::testing::Test {
 protected:
  void SetUp() override {
    temp_ = std::make_unique<TempDir>(std::string("malformed_") +
                                      ::testing::UnitTest::GetInstance()->current_test_info()->name());
    dir_ = temp_->path();
  }
  void TearDown() override { temp_.reset(); }

  std::string Write(const std::string& name, const std::string& bytes) const {
    const std::string path = (dir_ / name).string();
    std::ofstream out(path, std::ios::binary);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    return path;
  }

  std::string ReadBytes(const std::string& path) const {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  }

  // Reads `bytes` as file `name` and expects an Error whose single line names the file and contains `what`.
  void ExpectError(const std::string& name, const std::string& bytes, const std::string& what) const {
    SCOPED_TRACE(name);
    const std::string path = Write(name, bytes);
    try {
      ReadNoisyMesh(path);
      ADD_FAILURE() << "no error for " << name;
    } catch (const Error& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find(path), std::string::npos) << message;
      EXPECT_NE(message.find(what), std::string::npos) << message;
      EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    }
  }

  std::unique_ptr<TempDir> temp_;
  fs::path dir_;
};

Mesh SmallMesh() {
  Mesh mesh;
  mesh.V.resize(5, 3);
  mesh.V << 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0.5, 0.5, 1;
  mesh.F.resize(4, 3);
  mesh.F << 0, 1, 4, 1, 2, 4, 2, 3, 4, 3, 0, 4;
  return mesh;
}

const char kPlyHead[] = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n";

TEST_F(MalformedMeshTest, EmptyFiles) {
  ExpectError("empty.ply", "", "empty");
  ExpectError("empty.obj", "", "empty");
  ExpectError("empty.off", "", "empty");
  ExpectError("text.obj", "\nnot a mesh\n", "no vertices");  // comments alone are an empty mesh: AnEmptyObjReadsBack
  ExpectError("blank.off", "  \n", "empty");
}

TEST_F(MalformedMeshTest, MissingFile) {
  EXPECT_THROW(ReadMesh((dir_ / "nothing.ply").string()), Error);
  EXPECT_THROW(ReadMesh(dir_.string() + "/"), Error);  // no extension
  fs::create_directories(dir_ / "folder.ply");
  EXPECT_THROW(ReadMesh((dir_ / "folder.ply").string()), Error);
}

TEST_F(MalformedMeshTest, BadPlyHeaders) {
  ExpectError("magic.ply", "plx\nformat ascii 1.0\nend_header\n", "not a PLY file");
  ExpectError("noend.ply", std::string(kPlyHead), "no 'end_header'");
  ExpectError("noformat.ply", "ply\nelement vertex 0\nproperty float x\nend_header\n", "no 'format'");
  ExpectError("format.ply", "ply\nformat binary_middle_endian 1.0\nend_header\n", "unknown format");
  ExpectError("type.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\nend_header\n",
              "unknown type");
  ExpectError("count.ply", "ply\nformat ascii 1.0\nelement vertex -3\nend_header\n", "non-negative integer");
  ExpectError("orphan.ply", "ply\nformat ascii 1.0\nproperty float x\nend_header\n", "before any element");
  ExpectError("keyword.ply", "ply\nformat ascii 1.0\nbogus line\nend_header\n", "unknown keyword");
  ExpectError("listcount.ply",
              std::string(kPlyHead) + "element face 1\nproperty list float int vertex_indices\nend_header\n",
              "not an integer type");
  ExpectError("noxyz.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n",
              "lacks scalar x, y and z");
  ExpectError("novertex.ply", "ply\nformat ascii 1.0\nelement stuff 0\nend_header\n", "no 'vertex' element");
  ExpectError("nolist.ply", std::string(kPlyHead) + "element face 1\nproperty int flags\nend_header\n0 0 0\n1 0 0\n0 1 0\n7\n",
              "lacks a 'vertex_indices'");
}

TEST_F(MalformedMeshTest, AsciiValuesMustFitTheirDeclaredType) {
  // A binary file could not hold these values: readers that honour the header would read other numbers.
  const std::string faces = "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
  ExpectError("float.ply", std::string(kPlyHead) + faces + "0 0 0\n1e39 0 0\n0 1 0\n3 0 1 2\n",
              "value out of range for its declared type float");
  ExpectError("count.ply", std::string(kPlyHead) + faces + "0 0 0\n1 0 0\n0 1 0\n300 0 1 2\n",
              "value out of range for its declared type uchar");
  ExpectError("colour.ply",
              std::string(kPlyHead) + "property uchar red\nend_header\n0 0 0 255\n1 0 0 256\n0 1 0 0\n",
              "'vertex' element 1 property 'red': value out of range for its declared type uchar");
  ExpectError("fraction.ply",
              std::string(kPlyHead) + "property int flags\nend_header\n0 0 0 1\n1 0 0 1.5\n0 1 0 0\n",
              "out of range for its declared type int");
  // The same values where they fit read as before (a double coordinate, a whole number written with a point).
  const std::string fits = "ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\nproperty float y\n"
                           "property float z\nproperty uchar red\n" + faces +
                           "1e39 0 0 255.0\n1 0 0 0\n0 1 0 7\n3 0 1 2\n";
  std::ofstream(dir_ / "fits.ply") << fits;
  const Mesh mesh = ReadMesh((dir_ / "fits.ply").string());
  EXPECT_EQ(mesh.V(0, 0), 1e39);
  EXPECT_EQ(mesh.num_faces(), 1);
}

TEST_F(MalformedMeshTest, AbsurdDeclaredCountsAreRejectedBeforeAllocating) {
  // 10^12 vertices, or 10^12 faces, in files of a few hundred bytes.
  const std::string huge_v =
      "ply\nformat binary_little_endian 1.0\nelement vertex 1000000000000\nproperty float x\n"
      "property float y\nproperty float z\nend_header\n" + std::string(600, '\0');
  ExpectError("huge_v.ply", huge_v, "truncated file or wrong count");
  const std::string huge_f =
      "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
      "property float z\nelement face 1000000000000\nproperty list uchar int vertex_indices\nend_header\n" +
      std::string(600, '\0');
  ExpectError("huge_f.ply", huge_f, "truncated file or wrong count");
  ExpectError("huge_a.ply", std::string(kPlyHead).replace(std::string(kPlyHead).find(" 3\n"), 3, " 99999999999\n") +
                                "end_header\n0 0 0\n",
              "truncated file or wrong count");
  // Elements the reader skips are bounded too (else a skip loop would run 10^18 times).
  ExpectError("huge_skip.ply",
              "ply\nformat binary_little_endian 1.0\nelement junk 1000000000000000000\nproperty uchar a\n"
              "end_header\n" + std::string(100, 'x'),
              "truncated file or wrong count");
  // A single face claiming 4 billion indices.
  std::string list = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                     "property float z\nelement face 1\nproperty list uint int vertex_indices\nend_header\n";
  list += std::string(36, '\0');
  list += std::string(4, '\xff');
  list += std::string(12, '\0');
  ExpectError("huge_list.ply", list, "truncated");
  ExpectError("huge.off", "OFF\n1000000000000 1000000000000 0\n0 0 0\n", "truncated file or wrong counts");
  ExpectError("huge2.off", "OFF\n3 99999999 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "truncated file or wrong counts");
  ExpectError("hugepoly.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n2000000000 0 1 2\n", "truncated");
}

TEST_F(MalformedMeshTest, WrongCounts) {
  // Four vertices declared, three given: the face line is read as the fourth vertex, then faces run out.
  ExpectError("fewer.ply",
              "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
              "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
              "truncated");
  ExpectError("more.ply",
              std::string(kPlyHead) + "end_header\n0 0 0\n1 0 0\n0 1 0\n5 5 5\n", "more data after the last element");
  ExpectError("fewer.off", "OFF\n4 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "");
  ExpectError("fewerfaces.off", "OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "truncated");
  ExpectError("shortface.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n4 0 1 2\n", "fewer than its 4 vertices");
}

TEST_F(MalformedMeshTest, OutOfRangeIndices) {
  ExpectError("range.ply", std::string(kPlyHead) +
                               "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                               "0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n",
              "uses vertex 3 but there are 3 vertices");
  ExpectError("negative.ply", std::string(kPlyHead) +
                                  "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                                  "0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n",
              "out of range");
  ExpectError("range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "uses vertex 3 but there are 3 vertices");
  ExpectError("zero.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", "index 0");
  ExpectError("relative.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n", "refers before the first vertex");
  ExpectError("normal.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//2\n", "uses normal 2");
  ExpectError("range.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", "uses vertex 3 but there are 3 vertices");
  ExpectError("huge.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999999999999\n", "is not v, v/vt");
}

TEST_F(MalformedMeshTest, BadNumbersAndFaces) {
  ExpectError("word.obj", "v 0 0 0\nv 1 zero 0\n", "is not a number");
  ExpectError("short.obj", "v 0 0\n", "fewer than 3 coordinates");
  ExpectError("twoface.obj", "v 0 0 0\nv 1 0 0\nf 1 2\n", "at least 3 needed");
  ExpectError("corner.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/x/1 2 3\n", "bad texture index");
  ExpectError("word.ply", std::string(kPlyHead) + "end_header\n0 0 0\n1 0 0\n0 one 0\n", "expected a number");
  ExpectError("twoface.ply", std::string(kPlyHead) +
                                 "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                                 "0 0 0\n1 0 0\n0 1 0\n2 0 1\n",
              "at least 3 needed");
  ExpectError("float.ply", std::string(kPlyHead) +
                               "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                               "0 0 0\n1 0 0\n0 1 0\n3 0 1.5 2\n",
              "expected an integer");
  ExpectError("word.off", "OFF\n3 1 0\n0 0 0\n1 x 0\n0 1 0\n3 0 1 2\n", "is not a number");
  ExpectError("magic.off", "OBJ\n3 1 0\n", "not an OFF file");
  ExpectError("variant.off", "4OFF\n3 1 0\n", "unsupported OFF variant");
  ExpectError("binary.off", "OFF BINARY\n", "binary OFF");
  ExpectError("twoface.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n2 0 1    \n", "at least 3 needed");
}

TEST_F(MalformedMeshTest, NanCoordinatesAreRead) {
  const Mesh mesh = ReadMesh(Write("nan.obj", "v nan 0 0\nv 1 0 0\nv 0 1 -inf\nf 1 2 3\n"));
  EXPECT_TRUE(std::isnan(mesh.V(0, 0)));
  EXPECT_TRUE(std::isinf(mesh.V(2, 2)));
  // Literals beyond double range saturate like strtod instead of failing.
  const Mesh big = ReadMesh(Write("big.obj", "v 1e999 1e-999 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"));
  EXPECT_TRUE(std::isinf(big.V(0, 0)));
  EXPECT_EQ(big.V(0, 1), 0.0);
  // A long literal is read whole: cut to 512 characters, 1e-000…0400 read as 1.
  const Mesh tiny =
      ReadMesh(Write("long.obj", "v 1e-" + std::string(600, '0') + "400 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"));
  EXPECT_EQ(tiny.V(0, 0), 0.0);
}

// An ASCII PLY's body errors name the line of the file (they counted from the line after end_header).
TEST_F(MalformedMeshTest, AsciiPlyErrorsNameTheFileLine) {
  // Lines 1-7 are the header, 8 and 9 the first two vertices: the bad number is on line 10.
  ExpectError("line.ply", std::string(kPlyHead) + "end_header\n0 0 0\n1 0 0\n0 abc 0\n", ": line 10: ");
}

// An empty mesh written as OBJ (only the writer's comment line) reads back as an empty mesh, as PLY and OFF do;
// a file without any line stays an error.
TEST_F(MalformedMeshTest, AnEmptyObjReadsBack) {
  const std::string path = (dir_ / "empty.obj").string();
  WriteMesh(Mesh{}, path);
  const Mesh back = ReadMesh(path);
  EXPECT_EQ(back.num_vertices(), 0);
  EXPECT_EQ(back.num_faces(), 0);
  EXPECT_EQ(ReadMesh(Write("blank.obj", "\n\n# only a comment\n")).num_vertices(), 0);
  ExpectError("nothing.obj", "", "empty");
}

TEST_F(MalformedMeshTest, GarbageBytes) {
  std::mt19937 rng(42);
  std::uniform_int_distribution<int> byte(0, 255);
  for (int trial = 0; trial < 20; ++trial) {
    std::string garbage(1000, '\0');
    for (char& c : garbage) c = static_cast<char>(byte(rng));
    for (const std::string ext : {"ply", "obj", "off"}) {
      const std::string path = Write("garbage." + ext, garbage);
      EXPECT_THROW(ReadMesh(path), Error) << ext << " trial " << trial;
    }
    // Garbage after a valid PLY header.
    const std::string path = Write("garbage_body.ply", std::string(kPlyHead) +
                                                           "element face 5\nproperty list uchar int vertex_indices\n"
                                                           "end_header\n" + garbage.substr(0, 50));
    EXPECT_THROW(ReadMesh(path), Error) << trial;
  }
}

// Every strict prefix of a valid PLY or OFF file is an error (counts say more must follow); OBJ prefixes may
// be valid OBJ files. None may crash.
TEST_F(MalformedMeshTest, TruncatedFilesAtEveryLength) {
  const Mesh mesh = SmallMesh();
  struct Case {
    std::string file;
    PlyEncoding encoding;
    bool prefix_is_error;
  };
  const Case cases[] = {{"t_le.ply", PlyEncoding::kBinaryLittleEndian, true},
                        {"t_be.ply", PlyEncoding::kBinaryBigEndian, true},
                        {"t_ascii.ply", PlyEncoding::kAscii, true},
                        {"t.off", PlyEncoding::kAscii, true},
                        {"t.obj", PlyEncoding::kAscii, false}};
  for (const Case& c : cases) {
    MeshWriteOptions options;
    options.ply_encoding = c.encoding;
    const std::string full_path = (dir_ / c.file).string();
    WriteMesh(mesh, full_path, options);
    const std::string full = ReadBytes(full_path);
    for (size_t length = 0; length + 1 < full.size(); ++length) {
      // Cutting ascii files inside the final newline or the last number can leave a valid file.
      if (c.encoding == PlyEncoding::kAscii && length + 3 >= full.size()) continue;
      const std::string path = Write("cut_" + c.file, full.substr(0, length));
      if (c.prefix_is_error) {
        EXPECT_THROW(ReadMesh(path), Error) << c.file << " cut at " << length << " of " << full.size();
      } else {
        try {
          ReadMesh(path);
        } catch (const Error&) {
        }
      }
    }
  }
}

}  // namespace
}  // namespace rangebayes

// Mesh I/O speed: read and write a 1M-face binary PLY (the target: each under 1 s on 2 cores), plus
// ascii PLY, OBJ and OFF for comparison and an OBJ read of a ~100k-face mesh.
//
//   ./build/release/bench/bench_mesh_io [--benchmark_filter=...] [--rb_tmp=/tmp]
//
// The meshes are generated (a bumpy n×n grid), written to the temp folder once and removed at exit.
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "core/mesh_io.h"

namespace rangebayes {
namespace {

std::string g_tmp = "/tmp";
std::vector<std::string> g_files;

// A grid of n×n vertices (2(n−1)² triangles) on a wavy height field, so that coordinates use all digits.
Mesh BumpyGrid(int n) {
  Mesh mesh;
  mesh.V.resize(static_cast<Eigen::Index>(n) * n, 3);
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      const double u = x / static_cast<double>(n - 1), v = y / static_cast<double>(n - 1);
      mesh.V.row(static_cast<Eigen::Index>(y) * n + x) << u, v, 0.05 * std::sin(17.0 * u) * std::cos(13.0 * v);
    }
  }
  mesh.F.resize(2 * static_cast<Eigen::Index>(n - 1) * (n - 1), 3);
  Eigen::Index f = 0;
  for (int y = 0; y + 1 < n; ++y) {
    for (int x = 0; x + 1 < n; ++x) {
      const int a = y * n + x, b = a + 1, c = a + n, d = c + 1;
      mesh.F.row(f++) << a, b, d;
      mesh.F.row(f++) << a, d, c;
    }
  }
  return mesh;
}

// 709² vertices: 1,002,528 faces. 225²: 100,352 faces.
constexpr int kMillionGrid = 709;
constexpr int kHundredThousandGrid = 225;

const Mesh& MillionFaces() {
  static const Mesh mesh = BumpyGrid(kMillionGrid);
  return mesh;
}
const Mesh& HundredThousandFaces() {
  static const Mesh mesh = BumpyGrid(kHundredThousandGrid);
  return mesh;
}

std::string TmpFile(const std::string& name) {
  const std::string path = g_tmp + "/rb_bench_mesh_io_" + name;
  g_files.push_back(path);
  return path;
}

void Write(benchmark::State& state, const Mesh& mesh, const std::string& name, PlyEncoding encoding) {
  MeshWriteOptions options;
  options.ply_encoding = encoding;
  const std::string path = TmpFile(name);
  for (auto _ : state) WriteMesh(mesh, path, options);
  state.counters["faces"] = static_cast<double>(mesh.num_faces());
  state.SetItemsProcessed(state.iterations() * mesh.num_faces());
}

void Read(benchmark::State& state, const Mesh& mesh, const std::string& name, PlyEncoding encoding) {
  MeshWriteOptions options;
  options.ply_encoding = encoding;
  const std::string path = TmpFile(name);
  WriteMesh(mesh, path, options);
  for (auto _ : state) {
    Mesh back = ReadMesh(path);
    benchmark::DoNotOptimize(back.V.data());
    if (back.num_faces() != mesh.num_faces()) state.SkipWithError("face count differs after reading");
  }
  state.counters["faces"] = static_cast<double>(mesh.num_faces());
  state.SetItemsProcessed(state.iterations() * mesh.num_faces());
}

void BM_WritePlyBinary_1M(benchmark::State& s) { Write(s, MillionFaces(), "w1m.ply", PlyEncoding::kBinaryLittleEndian); }
void BM_ReadPlyBinary_1M(benchmark::State& s) { Read(s, MillionFaces(), "r1m.ply", PlyEncoding::kBinaryLittleEndian); }
void BM_WritePlyBigEndian_1M(benchmark::State& s) { Write(s, MillionFaces(), "w1mbe.ply", PlyEncoding::kBinaryBigEndian); }
void BM_ReadPlyBigEndian_1M(benchmark::State& s) { Read(s, MillionFaces(), "r1mbe.ply", PlyEncoding::kBinaryBigEndian); }
void BM_WritePlyAscii_1M(benchmark::State& s) { Write(s, MillionFaces(), "w1ma.ply", PlyEncoding::kAscii); }
void BM_ReadPlyAscii_1M(benchmark::State& s) { Read(s, MillionFaces(), "r1ma.ply", PlyEncoding::kAscii); }
void BM_WriteObj_1M(benchmark::State& s) { Write(s, MillionFaces(), "w1m.obj", PlyEncoding::kAscii); }
void BM_ReadObj_1M(benchmark::State& s) { Read(s, MillionFaces(), "r1m.obj", PlyEncoding::kAscii); }
void BM_ReadOff_1M(benchmark::State& s) { Read(s, MillionFaces(), "r1m.off", PlyEncoding::kAscii); }
void BM_WriteObj_100k(benchmark::State& s) { Write(s, HundredThousandFaces(), "w100k.obj", PlyEncoding::kAscii); }
void BM_ReadObj_100k(benchmark::State& s) { Read(s, HundredThousandFaces(), "r100k.obj", PlyEncoding::kAscii); }

BENCHMARK(BM_WritePlyBinary_1M)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ReadPlyBinary_1M)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_WritePlyBigEndian_1M)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ReadPlyBigEndian_1M)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_WritePlyAscii_1M)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ReadPlyAscii_1M)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_WriteObj_1M)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ReadObj_1M)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ReadOff_1M)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_WriteObj_100k)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ReadObj_100k)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace rangebayes

int main(int argc, char** argv) {
  // Our own flag first; Google Benchmark rejects flags it does not know.
  std::vector<char*> args;
  for (int i = 0; i < argc; ++i) {
    if (std::strncmp(argv[i], "--rb_tmp=", 9) == 0) {
      rangebayes::g_tmp = argv[i] + 9;
    } else {
      args.push_back(argv[i]);
    }
  }
  int count = static_cast<int>(args.size());
  benchmark::Initialize(&count, args.data());
  if (benchmark::ReportUnrecognizedArguments(count, args.data())) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  for (const std::string& path : rangebayes::g_files) std::remove(path.c_str());
  return 0;
}

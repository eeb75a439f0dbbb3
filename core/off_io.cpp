// OFF reader and writer ([ST][C][N]OFF ascii; per-vertex normals from NOFF, colours skipped).
#include <limits>
#include <string>
#include <vector>

#include "core/mesh_io_internal.h"

namespace rangebayes::mesh_io {
namespace {

class OffParser {
 public:
  OffParser(std::string_view bytes, const std::string& name, MeshReadSummary* summary)
      : cursor_(bytes.data(), bytes.data() + bytes.size()),
        end_(bytes.data() + bytes.size()),
        name_(name),
        summary_(summary) {}

  NoisyMesh Parse() {
    SkipSpaceAndComments();
    RB_CHECK(!cursor_.AtEnd(), name_, ": empty file");
    const std::string_view keyword = cursor_.Word();
    bool normals = false;
    const bool is_off = keyword.size() >= 3 && keyword.substr(keyword.size() - 3) == "OFF";
    RB_CHECK(is_off, name_, ": not an OFF file (it must start with OFF, COFF, NOFF or similar)");
    for (const char c : keyword.substr(0, keyword.size() - 3)) {
      RB_CHECK(c == 'S' || c == 'T' || c == 'C' || c == 'N', name_, ": unsupported OFF variant '", keyword, "'");
      normals = normals || c == 'N';
    }
    if (!cursor_.AtLineEnd()) {
      const std::string_view next = cursor_.Word();
      RB_CHECK(next != "BINARY", name_, ": binary OFF is not supported");
      cursor_.Seek(next.data());  // counts on the header line
    }
    const int64_t nv = Count("vertex");
    const int64_t nf = Count("face");
    cursor_.NextLine();  // the edge count (and anything else on the line) is not needed

    // Every vertex line holds at least "0 0 0\n", every face line "3 0 0 0\n": bound counts by bytes left.
    const auto remaining = static_cast<uint64_t>(end() - cursor_.position());
    const uint64_t needed_v = static_cast<uint64_t>(nv) * (normals ? 12 : 6);
    const uint64_t needed_f = static_cast<uint64_t>(nf) * 8;
    RB_CHECK(static_cast<uint64_t>(nv) <= remaining / 6 && static_cast<uint64_t>(nf) <= remaining / 8 &&
                 needed_v + needed_f <= remaining + 1,
             name_, ": header declares ", nv, " vertices and ", nf, " faces but only ", remaining,
             " bytes follow: truncated file or wrong counts");
    RB_CHECK(nv <= std::numeric_limits<int>::max() && nf <= std::numeric_limits<int>::max() / 3, name_,
             ": too many vertices or faces");

    NoisyMesh result;
    Mesh& mesh = result.mesh;
    int64_t vertex_extras = 0;
    mesh.V.resize(nv, 3);
    if (normals) mesh.N.resize(nv, 3);
    for (int64_t i = 0; i < nv; ++i) {
      SkipSpaceAndComments();
      for (int d = 0; d < 3; ++d) mesh.V(i, d) = Number("vertex", i);
      if (normals) {
        for (int d = 0; d < 3; ++d) mesh.N(i, d) = Number("vertex normal", i);
      }
      if (!cursor_.AtLineEnd() && cursor_.Peek() != '#') ++vertex_extras;  // colours, texture coordinates
      cursor_.NextLine();
    }
    std::vector<int> triangles;
    triangles.reserve(static_cast<size_t>(3 * nf));
    std::vector<int> polygon;
    PolygonSplitter splitter;
    int64_t face_extras = 0;
    for (int64_t f = 0; f < nf; ++f) {
      SkipSpaceAndComments();
      if (cursor_.AtEnd()) Fail(StrCat("truncated: file ends in face ", f, " of ", nf));
      int64_t n = 0;
      if (!cursor_.ParseInt(&n)) Fail(StrCat("face ", f, ": vertex count '", cursor_.Word().substr(0, 40), "' is not an integer"));
      if (n < 3) Fail(StrCat("face ", f, " has ", n, " vertices (at least 3 needed)"));
      if (static_cast<uint64_t>(n) > static_cast<uint64_t>(end() - cursor_.position())) {
        Fail(StrCat("truncated: file ends in face ", f, " of ", nf));
      }
      polygon.resize(static_cast<size_t>(n));
      for (int64_t c = 0; c < n; ++c) {
        cursor_.SkipBlanks();
        if (cursor_.AtLineEnd()) Fail(StrCat("face ", f, " lists fewer than its ", n, " vertices"));
        int64_t v = 0;
        if (!cursor_.ParseInt(&v)) Fail(StrCat("face ", f, ": vertex index '", cursor_.Word().substr(0, 40), "' is not an integer"));
        if (v < 0 || v >= nv) Fail(StrCat("face ", f, " uses vertex ", v, " but there are ", nv, " vertices"));
        polygon[static_cast<size_t>(c)] = static_cast<int>(v);
      }
      if (triangles.size() / 3 + static_cast<size_t>(n) > static_cast<size_t>(std::numeric_limits<int>::max() / 3)) {
        Fail("too many faces");
      }
      if (n > 3) {
        splitter.Add(polygon.data(), nullptr, polygon.size(), &triangles, nullptr, mesh.V.data(),
                     static_cast<size_t>(mesh.V.rows()));
      } else {
        triangles.insert(triangles.end(), polygon.begin(), polygon.end());
      }
      if (!cursor_.AtLineEnd() && cursor_.Peek() != '#') ++face_extras;  // face colours
      cursor_.NextLine();
    }
    SkipSpaceAndComments();
    if (!cursor_.AtEnd()) summary_->notices.push_back(StrCat("ignored data after the last face (line ", cursor_.line(), ")"));
    splitter.Finish(mesh.V, &triangles, nullptr, summary_);
    if (vertex_extras > 0) {
      summary_->notices.push_back(StrCat("ignored the values after the position", normals ? " and normal" : "",
                                         " (colours, texture coordinates) of ", vertex_extras, " vertices"));
    }
    if (face_extras > 0) summary_->notices.push_back(StrCat("ignored the colours of ", face_extras, " faces"));
    mesh.F = Eigen::Map<const Faces>(triangles.data(), static_cast<Eigen::Index>(triangles.size() / 3), 3);
    return result;
  }

 private:
  const char* end() const { return end_; }

  [[noreturn]] void Fail(const std::string& what) { RB_FAIL(name_, ": line ", cursor_.line(), ": ", what); }

  void SkipSpaceAndComments() {
    while (true) {
      cursor_.SkipWhitespace();
      if (cursor_.Peek() != '#') return;
      cursor_.NextLine();
    }
  }

  int64_t Count(const char* what) {
    SkipSpaceAndComments();
    int64_t n = 0;
    if (cursor_.AtEnd()) Fail(StrCat("truncated: no ", what, " count"));
    if (!cursor_.ParseInt(&n) || n < 0) Fail(StrCat(what, " count '", cursor_.Word().substr(0, 40), "' is not a non-negative integer"));
    return n;
  }

  double Number(const char* what, int64_t index) {
    cursor_.SkipBlanks();
    if (cursor_.AtEnd()) Fail(StrCat("truncated: file ends in ", what, " ", index));
    if (cursor_.AtLineEnd()) Fail(StrCat(what, " ", index, " has too few values"));
    double value = 0;
    if (!cursor_.ParseDouble(&value)) Fail(StrCat(what, " ", index, ": '", cursor_.Word().substr(0, 40), "' is not a number"));
    return value;
  }

  TextCursor cursor_;
  const char* end_;
  const std::string& name_;
  MeshReadSummary* summary_;
};

void AppendPositions(std::string* out, const Vertices& V, const Normals* N, int precision) {
  for (Eigen::Index i = 0; i < V.rows(); ++i) {
    for (int d = 0; d < 3; ++d) {
      if (d > 0) out->push_back(' ');
      AppendDouble(out, V(i, d), precision);
    }
    if (N != nullptr) {
      for (int d = 0; d < 3; ++d) {
        out->push_back(' ');
        AppendDouble(out, (*N)(i, d), precision);
      }
    }
    out->push_back('\n');
  }
}

}  // namespace

NoisyMesh ParseOff(std::string_view bytes, const std::string& name, MeshReadSummary* summary) {
  OffParser parser(bytes, name, summary);
  return parser.Parse();
}

std::string FormatOff(const Mesh& mesh, const MeshWriteOptions& options) {
  const bool normals = options.write_vertex_normals && mesh.N.rows() == mesh.V.rows() && mesh.V.rows() > 0;
  std::string out;
  out.reserve(static_cast<size_t>(mesh.V.rows()) * (normals ? 120 : 60) + static_cast<size_t>(mesh.F.rows()) * 25);
  out += normals ? "NOFF\n" : "OFF\n";
  out += StrCat(mesh.V.rows(), " ", mesh.F.rows(), " 0\n");
  AppendPositions(&out, mesh.V, normals ? &mesh.N : nullptr, options.precision);
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
    out += "3";
    for (int k = 0; k < 3; ++k) {
      out.push_back(' ');
      AppendInt(&out, mesh.F(f, k));
    }
    out.push_back('\n');
  }
  return out;
}

std::string FormatPolygonOff(const Vertices& V, const std::vector<std::vector<int>>& polygons,
                             const MeshWriteOptions& options) {
  std::string out = "OFF\n";
  out += StrCat(V.rows(), " ", polygons.size(), " 0\n");
  AppendPositions(&out, V, nullptr, options.precision);
  for (const auto& polygon : polygons) {
    AppendInt(&out, static_cast<int64_t>(polygon.size()));
    for (const int v : polygon) {
      out.push_back(' ');
      AppendInt(&out, v);
    }
    out.push_back('\n');
  }
  return out;
}

}  // namespace rangebayes::mesh_io

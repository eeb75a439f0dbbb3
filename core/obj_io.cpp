// Wavefront OBJ reader and writer: `v`, `vn` and `f` statements (v, v/vt, v//vn, v/vt/vn corners, negative
// relative indices, polygons); everything else (vt, groups, materials, lines) is skipped, with a notice for what
// carries data (vertex colours, vt, materials).
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "core/mesh_io_internal.h"

namespace rangebayes::mesh_io {
namespace {

bool IsText(std::string_view word) {
  for (const char c : word) {
    const auto u = static_cast<unsigned char>(c);
    if (u < 0x20 || u >= 0x7f) return false;
  }
  return true;
}

class ObjParser {
 public:
  ObjParser(std::string_view bytes, const std::string& name, MeshReadSummary* summary)
      : cursor_(bytes.data(), bytes.data() + bytes.size()), name_(name), summary_(summary) {}

  NoisyMesh Parse() {
    while (!cursor_.AtEnd()) {
      cursor_.SkipBlanks();
      const char c = cursor_.Peek();
      if (c == '\n' || c == '#' || c == '\0') {
        if (c == '#') ++comment_lines_;
        cursor_.NextLine();
        continue;
      }
      ++statement_lines_;
      const std::string_view keyword = cursor_.Word();
      if (keyword == "v") {
        ReadTriple(&positions_, "vertex");
        if (!cursor_.AtLineEnd() && cursor_.Peek() != '#') ++vertex_extras_;
      } else if (keyword == "vn") {
        ReadTriple(&normals_, "normal");
      } else if (keyword == "f") {
        ReadFace();
      } else if (keyword == "vt") {
        ++texture_coordinates_;  // a Mesh holds none
      } else if (keyword == "usemtl" || keyword == "mtllib") {
        ++material_statements_;  // nor materials
      } else if (keyword == "g" || keyword == "o" || keyword == "s" || keyword == "vp") {
        // Grouping and smoothing groups carry nothing for the geometry.
      } else {
        RB_CHECK(IsText(keyword), name_, ": line ", cursor_.line(), ": not OBJ text (binary data?)");
        ++other_statements_;
      }
      cursor_.NextLine();
    }
    return Finish();
  }

 private:
  [[noreturn]] void Fail(const std::string& what) { RB_FAIL(name_, ": line ", cursor_.line(), ": ", what); }

  void ReadTriple(std::vector<double>* out, const char* what) {
    for (int k = 0; k < 3; ++k) {
      cursor_.SkipBlanks();
      double value = 0;
      if (cursor_.AtLineEnd()) Fail(StrCat(what, " has fewer than 3 coordinates"));
      if (!cursor_.ParseDouble(&value)) Fail(StrCat(what, " coordinate '", cursor_.Word().substr(0, 40),
                                                    "' is not a number"));
      out->push_back(value);
    }
    // A 4th value (w) or vertex colours may follow; a Mesh keeps neither.
  }

  // Resolves a 1-based or negative (relative) OBJ index against the `count` items read so far.
  int Resolve(int64_t index, size_t count, const char* what) {
    if (index == 0) Fail(StrCat(what, " index 0 (OBJ indices start at 1)"));
    if (index > 0) {
      if (index > std::numeric_limits<int>::max()) Fail(StrCat(what, " index ", index, " out of range"));
      return static_cast<int>(index - 1);  // checked against the final count at the end (forward references)
    }
    const int64_t resolved = static_cast<int64_t>(count) + index;
    if (resolved < 0) Fail(StrCat(what, " index ", index, " refers before the first ", what));
    return static_cast<int>(resolved);
  }

  bool ParseIndex(int64_t* value) { return cursor_.ParseInt(value, '/'); }

  void ReadFace() {
    corner_vertex_.clear();
    corner_normal_.clear();
    while (!cursor_.AtLineEnd() && cursor_.Peek() != '#') {  // a comment may end the line
      int64_t v = 0;
      if (!ParseIndex(&v)) Fail(StrCat("face corner '", cursor_.Word().substr(0, 40), "' is not v, v/vt, v//vn or v/vt/vn"));
      int normal = -1;
      if (cursor_.Peek() == '/') {
        cursor_.Advance();
        if (cursor_.Peek() != '/') {
          int64_t vt = 0;
          if (!TextCursor::IsSpace(cursor_.Peek()) && cursor_.Peek() != '\0' && !ParseIndex(&vt)) {
            Fail("bad texture index in a face corner");
          }
        }
        if (cursor_.Peek() == '/') {
          cursor_.Advance();
          int64_t vn = 0;
          if (!TextCursor::IsSpace(cursor_.Peek()) && cursor_.Peek() != '\0') {
            if (!cursor_.ParseInt(&vn)) Fail("bad normal index in a face corner");
            normal = Resolve(vn, normals_.size() / 3, "normal");
          }
        }
      }
      if (!TextCursor::IsSpace(cursor_.Peek()) && cursor_.Peek() != '\0') Fail("bad face corner");
      corner_vertex_.push_back(Resolve(v, positions_.size() / 3, "vertex"));
      corner_normal_.push_back(normal);
    }
    const size_t n = corner_vertex_.size();
    if (n < 3) Fail(StrCat("face has ", n, " vertices (at least 3 needed)"));
    if (triangles_.size() / 3 + n > static_cast<size_t>(std::numeric_limits<int>::max() / 3)) Fail("too many faces");
    for (const int normal : corner_normal_) any_corner_normal_ = any_corner_normal_ || normal >= 0;
    if (n > 3) {
      splitter_.Add(corner_vertex_.data(), corner_normal_.data(), n, &triangles_, &triangle_normals_, positions_.data(),
                    positions_.size() / 3);
      return;
    }
    triangles_.insert(triangles_.end(), corner_vertex_.begin(), corner_vertex_.end());
    triangle_normals_.insert(triangle_normals_.end(), corner_normal_.begin(), corner_normal_.end());
  }

  NoisyMesh Finish() {
    const size_t nv = positions_.size() / 3;
    // Comments alone are an empty mesh (what the writer makes of one); no line at all, or only lines that are no
    // OBJ statement, is not an OBJ file.
    const bool only_comments = comment_lines_ > 0 && statement_lines_ == 0;
    RB_CHECK(nv > 0 || !triangles_.empty() || only_comments, name_, ": no vertices (empty file or not an OBJ file)");
    RB_CHECK(nv <= static_cast<size_t>(std::numeric_limits<int>::max()), name_, ": too many vertices");
    NoisyMesh result;
    Mesh& mesh = result.mesh;
    mesh.V = Eigen::Map<const Vertices>(positions_.data(), static_cast<Eigen::Index>(nv), 3);
    splitter_.Finish(mesh.V, &triangles_, &triangle_normals_, summary_);
    mesh.F = Eigen::Map<const Faces>(triangles_.data(), static_cast<Eigen::Index>(triangles_.size() / 3), 3);
    try {
      CheckFaceIndices(mesh.F, static_cast<int64_t>(nv), "face");
    } catch (const Error& e) {
      RB_FAIL(name_, ": ", e.what(), splitter_.count() > 0 ? " (counting triangles after splitting polygons)" : "");
    }
    const size_t nn = normals_.size() / 3;
    for (const int n : triangle_normals_) {
      RB_CHECK(n < 0 || static_cast<size_t>(n) < nn, name_, ": a face uses normal ", n + 1, " but there are ", nn,
               " normals");
    }
    AssignVertexNormals(&mesh);
    if (vertex_extras_ > 0) {
      summary_->notices.push_back(
          StrCat("ignored the values after x y z (colours or w) of ", vertex_extras_, " vertices"));
    }
    if (texture_coordinates_ > 0) {
      summary_->notices.push_back(StrCat("ignored ", texture_coordinates_, " texture coordinates (vt)"));
    }
    if (material_statements_ > 0) {
      summary_->notices.push_back(
          StrCat("ignored the materials (", material_statements_, " usemtl/mtllib statements)"));
    }
    if (other_statements_ > 0) {
      summary_->notices.push_back(StrCat("skipped ", other_statements_, " unsupported OBJ statements"));
    }
    return result;
  }

  // Per-vertex normals from `vn`: the file's own when each vertex always gets the same one (exact values),
  // the normalised mean of its corner normals otherwise.
  void AssignVertexNormals(Mesh* mesh) {
    const size_t nv = positions_.size() / 3;
    const size_t nn = normals_.size() / 3;
    if (nn == 0) return;
    if (!any_corner_normal_) {
      if (nn == nv) {
        mesh->N = Eigen::Map<const Normals>(normals_.data(), static_cast<Eigen::Index>(nn), 3);
      } else {
        summary_->notices.push_back(StrCat("ignored ", nn, " normals that no face uses (", nv, " vertices)"));
      }
      return;
    }
    // Our own writer's convention (and MeshLab's): normal i belongs to vertex i, also for unused vertices.
    if (nn == nv) {
      bool aligned = true;
      for (size_t i = 0; i < triangles_.size() && aligned; ++i) {
        aligned = triangle_normals_[i] < 0 || triangle_normals_[i] == triangles_[i];
      }
      if (aligned) {
        mesh->N = Eigen::Map<const Normals>(normals_.data(), static_cast<Eigen::Index>(nn), 3);
        return;
      }
    }
    std::vector<int> first(nv, -1);
    std::vector<char> mixed(nv, 0);
    for (size_t i = 0; i < triangles_.size(); ++i) {
      const int n = triangle_normals_[i];
      if (n < 0) continue;
      const auto v = static_cast<size_t>(triangles_[i]);
      if (first[v] < 0) {
        first[v] = n;
      } else if (first[v] != n) {
        mixed[v] = 1;
      }
    }
    Normals N = Normals::Zero(static_cast<Eigen::Index>(nv), 3);
    bool any_mixed = false;
    for (size_t i = 0; i < triangles_.size(); ++i) {
      const int n = triangle_normals_[i];
      const auto v = static_cast<size_t>(triangles_[i]);
      if (n < 0 || !mixed[v]) continue;
      any_mixed = true;
      N.row(static_cast<Eigen::Index>(v)) +=
          Eigen::RowVector3d(normals_[3 * n], normals_[3 * n + 1], normals_[3 * n + 2]).normalized();
    }
    size_t missing = 0;
    for (size_t v = 0; v < nv; ++v) {
      const auto row = static_cast<Eigen::Index>(v);
      if (first[v] < 0) {
        ++missing;
      } else if (!mixed[v]) {
        const auto n = static_cast<size_t>(first[v]);
        N.row(row) << normals_[3 * n], normals_[3 * n + 1], normals_[3 * n + 2];
      } else {
        const double length = N.row(row).norm();
        if (length > 0) N.row(row) /= length;
      }
    }
    if (missing > 0) {
      summary_->notices.push_back(StrCat("ignored normals: ", missing, " vertices have none"));
      return;
    }
    if (any_mixed) summary_->notices.push_back("per-corner normals averaged into per-vertex normals");
    mesh->N = std::move(N);
  }

  TextCursor cursor_;
  const std::string& name_;
  MeshReadSummary* summary_;
  std::vector<double> positions_;
  std::vector<double> normals_;
  std::vector<int> triangles_;
  std::vector<int> triangle_normals_;
  std::vector<int> corner_vertex_;
  std::vector<int> corner_normal_;
  bool any_corner_normal_ = false;
  PolygonSplitter splitter_;
  int64_t vertex_extras_ = 0;
  int64_t texture_coordinates_ = 0;
  int64_t material_statements_ = 0;
  int64_t other_statements_ = 0;
  int64_t comment_lines_ = 0, statement_lines_ = 0;
};

void AppendVertexLines(std::string* out, const char* key, const Vertices& V, int precision) {
  for (Eigen::Index i = 0; i < V.rows(); ++i) {
    out->append(key);
    for (int d = 0; d < 3; ++d) {
      out->push_back(' ');
      AppendDouble(out, V(i, d), precision);
    }
    out->push_back('\n');
  }
}

}  // namespace

NoisyMesh ParseObj(std::string_view bytes, const std::string& name, MeshReadSummary* summary) {
  RB_CHECK(!bytes.empty(), name, ": empty file");
  ObjParser parser(bytes, name, summary);
  return parser.Parse();
}

std::string FormatObj(const Mesh& mesh, const MeshWriteOptions& options) {
  const bool corner = !options.corner_normals.empty();
  const bool vertex_normals = !corner && options.write_vertex_normals && mesh.N.rows() == mesh.V.rows() &&
                              mesh.V.rows() > 0;
  std::string out;
  out.reserve(static_cast<size_t>(mesh.V.rows()) * (vertex_normals ? 120 : 60) +
              static_cast<size_t>(mesh.F.rows()) * (vertex_normals || corner ? 50 : 25));
  out += "# written by rangebayes\n";
  AppendVertexLines(&out, "v", mesh.V, options.precision);
  if (corner) AppendVertexLines(&out, "vn", options.corner_normals.normals, options.precision);
  if (vertex_normals) AppendVertexLines(&out, "vn", mesh.N, options.precision);
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
    out.push_back('f');
    for (int k = 0; k < 3; ++k) {
      out.push_back(' ');
      AppendInt(&out, mesh.F(f, k) + 1);
      if (corner || vertex_normals) {
        out += "//";
        AppendInt(&out, (corner ? options.corner_normals.normal_index(f, k) : mesh.F(f, k)) + 1);
      }
    }
    out.push_back('\n');
  }
  return out;
}

std::string FormatPolygonObj(const Vertices& V, const std::vector<std::vector<int>>& polygons,
                             const MeshWriteOptions& options) {
  std::string out = "# written by rangebayes\n";
  AppendVertexLines(&out, "v", V, options.precision);
  for (const auto& polygon : polygons) {
    out.push_back('f');
    for (const int v : polygon) {
      out.push_back(' ');
      AppendInt(&out, v + 1);
    }
    out.push_back('\n');
  }
  return out;
}

}  // namespace rangebayes::mesh_io

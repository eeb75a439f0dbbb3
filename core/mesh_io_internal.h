// Internals shared by the PLY, OBJ and OFF readers and writers (not part of the public API).
#pragma once

#include <charconv>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "core/error.h"
#include "core/mesh_io.h"

namespace rangebayes::mesh_io {

// A PLY `range_grid` element: cell_vertex[y·width + x] is the vertex of cell (x, y) or -1 (empty: no vertex).
struct PlyRangeGrid {
  int width = 0;
  int height = 0;
  std::vector<int> cell_vertex;
};

// Each reader parses the whole file's bytes; `name` (the path) goes into every error message. ParsePly also
// reads a `range_grid` element into `grid` when it is not null (else the element is skipped).
NoisyMesh ParsePly(std::string_view bytes, const std::string& name, MeshReadSummary* summary,
                   PlyRangeGrid* grid = nullptr);
NoisyMesh ParseObj(std::string_view bytes, const std::string& name, MeshReadSummary* summary);
NoisyMesh ParseOff(std::string_view bytes, const std::string& name, MeshReadSummary* summary);

// Writers return the file's bytes; the caller writes them in one go.
std::string FormatPly(const NoisyMesh& mesh, const MeshWriteOptions& options);
std::string FormatObj(const Mesh& mesh, const MeshWriteOptions& options);
std::string FormatOff(const Mesh& mesh, const MeshWriteOptions& options);
std::string FormatPolygonPly(const Vertices& V, const std::vector<std::vector<int>>& polygons,
                             const MeshWriteOptions& options);
std::string FormatPolygonObj(const Vertices& V, const std::vector<std::vector<int>>& polygons,
                             const MeshWriteOptions& options);
std::string FormatPolygonOff(const Vertices& V, const std::vector<std::vector<int>>& polygons,
                             const MeshWriteOptions& options);

// A forward-only scanner over text. Whitespace handling is explicit so that line-based formats (OBJ, OFF)
// and token-based ones (ascii PLY) can share the number parsing.
class TextCursor {
 public:
  // first_line: the line number of `begin` in its file (a PLY body's first line follows its header).
  TextCursor(const char* begin, const char* end, int64_t first_line = 1) : p_(begin), end_(end), line_(first_line) {}

  bool AtEnd() const { return p_ >= end_; }
  const char* position() const { return p_; }
  int64_t line() const { return line_; }

  // Skips spaces and tabs (and \r), not newlines.
  void SkipBlanks() {
    while (p_ < end_ && (*p_ == ' ' || *p_ == '\t' || *p_ == '\r')) ++p_;
  }
  // Skips all whitespace, counting lines.
  void SkipWhitespace() {
    while (p_ < end_) {
      const char c = *p_;
      if (c == '\n') {
        ++line_;
      } else if (c != ' ' && c != '\t' && c != '\r' && c != '\f' && c != '\v') {
        break;
      }
      ++p_;
    }
  }
  // True when only blanks remain before the end of the line (or file).
  bool AtLineEnd() {
    SkipBlanks();
    return p_ >= end_ || *p_ == '\n';
  }
  // Moves past the next newline.
  void NextLine() {
    while (p_ < end_ && *p_ != '\n') ++p_;
    if (p_ < end_) {
      ++p_;
      ++line_;
    }
  }
  // The rest of the current line without its line break; moves past the line break.
  std::string_view ReadLine() {
    const char* start = p_;
    while (p_ < end_ && *p_ != '\n') ++p_;
    const char* stop = p_;
    if (stop > start && stop[-1] == '\r') --stop;
    if (p_ < end_) {
      ++p_;
      ++line_;
    }
    return {start, static_cast<size_t>(stop - start)};
  }
  // A run of non-whitespace characters (after blanks); empty at the end of a line.
  std::string_view Word() {
    SkipBlanks();
    const char* start = p_;
    while (p_ < end_ && !IsSpace(*p_)) ++p_;
    return {start, static_cast<size_t>(p_ - start)};
  }
  // Parses a number at the cursor (no leading whitespace skipped). False when there is none or when the
  // number is not followed by whitespace, the end, or (for integers) `stop`.
  bool ParseDouble(double* value) {
    const char* start = p_;
    if (start < end_ && *start == '+') ++start;
    const auto [ptr, ec] = std::from_chars(start, end_, *value);
    if (ec == std::errc::result_out_of_range) {
      // Denormal or huge literals: keep the file readable; strtod-like saturation is what users expect.
      return ParseOutOfRange(start, value);
    }
    if (ec != std::errc() || (ptr < end_ && !IsSpace(*ptr))) return false;
    p_ = ptr;
    return true;
  }
  bool ParseInt(int64_t* value, char stop = ' ') {
    const char* start = p_;
    if (start < end_ && *start == '+') ++start;
    const auto [ptr, ec] = std::from_chars(start, end_, *value);
    if (ec != std::errc() || (ptr < end_ && !IsSpace(*ptr) && *ptr != stop)) return false;
    p_ = ptr;
    return true;
  }
  // A character at the cursor, or '\0' at the end.
  char Peek() const { return p_ < end_ ? *p_ : '\0'; }
  void Advance() { ++p_; }
  // Moves back to `p` on the current line (to re-read a word).
  void Seek(const char* p) { p_ = p; }

  static bool IsSpace(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f' || c == '\v'; }

 private:
  bool ParseOutOfRange(const char* start, double* value);

  const char* p_;
  const char* end_;
  int64_t line_ = 1;
};

// Appends numbers as text: shortest round-trip form for doubles when precision ≥ 17, else %.{precision}g.
void AppendDouble(std::string* out, double value, int precision);
void AppendInt(std::string* out, int64_t value);

// Throws Error unless every face index lies in [0, num_vertices).
void CheckFaceIndices(const Faces& F, int64_t num_vertices, const char* what);

// The polygons (more than 3 corners) a reader splits into triangles. Add() appends a polygon's fan (n − 2
// triangles, so face numbers follow the file) and, when the polygon is not convex in its plane, replaces it by an
// ear-clipping triangulation of as many triangles (a fan folds a concave polygon over itself); a polygon with a
// corner beyond the `num_vertices` positions read so far (OBJ may use a vertex before it lists it) is kept and
// decided in Finish(), which also writes the summary's count and notice.
// `attributes` (OBJ's corner normals) run parallel to `triangles`, one value per triangle corner, and follow the
// corners they belong to; null where a reader has none.
class PolygonSplitter {
 public:
  // xyz: the positions read so far, three doubles a vertex (may be null when num_vertices is 0).
  void Add(const int* corners, const int* corner_attributes, size_t n, std::vector<int>* triangles,
           std::vector<int>* attributes, const double* xyz, size_t num_vertices);
  void Finish(const Vertices& V, std::vector<int>* triangles, std::vector<int>* attributes, MeshReadSummary* summary);
  int count() const { return count_; }

 private:
  // Ear-clips the polygon whose fan starts at triangle `first` when it is not convex.
  void Replace(const double* xyz, const int* corners, const int* corner_attributes, size_t n, size_t first,
               std::vector<int>* triangles, std::vector<int>* attributes);

  int count_ = 0;
  int concave_ = 0;
  std::vector<size_t> clipped_;  // scratch
  // Polygons left for Finish():
  std::vector<size_t> first_triangle_;
  std::vector<size_t> corner_start_{0};  // polygon p's corners: corners_[corner_start_[p] .. corner_start_[p + 1])
  std::vector<int> corners_;
  std::vector<int> corner_attributes_;  // parallel to corners_ when attributes are given
};

}  // namespace rangebayes::mesh_io

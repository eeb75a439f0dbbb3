// PLY reader and writer (ascii, binary little and big endian).
//
// A focused reader of our own rather than PCL's: PCL's PLY reader allocates what the header declares before
// it checks that the file can hold it (10^12 vertices in a 1 KB file), has no place for per-vertex
// covariance in our NoisyMesh layout without a second pass through a PointCloud, and is several times slower
// on 1M-face binary files than the memcpy loop here. It also lives outside core/, which must not use PCL.
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "core/mesh_io_internal.h"

namespace rangebayes::mesh_io {
namespace {

enum class PlyType { kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };

int SizeOf(PlyType type) {
  switch (type) {
    case PlyType::kInt8:
    case PlyType::kUint8:
      return 1;
    case PlyType::kInt16:
    case PlyType::kUint16:
      return 2;
    case PlyType::kInt32:
    case PlyType::kUint32:
    case PlyType::kFloat32:
      return 4;
    case PlyType::kFloat64:
      return 8;
  }
  return 1;
}

bool IsInteger(PlyType type) { return type != PlyType::kFloat32 && type != PlyType::kFloat64; }

// Whether `value` is one that `type` can hold (non-finite values pass for the float types).
bool FitsType(double value, PlyType type) {
  const auto integer_in = [value](double lo, double hi) {
    return value == std::floor(value) && value >= lo && value <= hi;
  };
  switch (type) {
    case PlyType::kInt8:
      return integer_in(-128.0, 127.0);
    case PlyType::kUint8:
      return integer_in(0.0, 255.0);
    case PlyType::kInt16:
      return integer_in(-32768.0, 32767.0);
    case PlyType::kUint16:
      return integer_in(0.0, 65535.0);
    case PlyType::kInt32:
      return integer_in(-2147483648.0, 2147483647.0);
    case PlyType::kUint32:
      return integer_in(0.0, 4294967295.0);
    case PlyType::kFloat32:
      return !std::isfinite(value) || std::abs(value) <= std::numeric_limits<float>::max();
    case PlyType::kFloat64:
      return true;
  }
  return true;
}

bool ParseType(std::string_view word, PlyType* type) {
  struct Name {
    std::string_view name;
    PlyType type;
  };
  static constexpr Name kNames[] = {
      {"char", PlyType::kInt8},     {"int8", PlyType::kInt8},       {"uchar", PlyType::kUint8},
      {"uint8", PlyType::kUint8},   {"short", PlyType::kInt16},     {"int16", PlyType::kInt16},
      {"ushort", PlyType::kUint16}, {"uint16", PlyType::kUint16},   {"int", PlyType::kInt32},
      {"int32", PlyType::kInt32},   {"uint", PlyType::kUint32},     {"uint32", PlyType::kUint32},
      {"float", PlyType::kFloat32}, {"float32", PlyType::kFloat32}, {"double", PlyType::kFloat64},
      {"float64", PlyType::kFloat64}};
  for (const Name& n : kNames) {
    if (n.name == word) {
      *type = n.type;
      return true;
    }
  }
  return false;
}

// The header's name of `type` (the first of its two spellings).
const char* TypeName(PlyType type) {
  switch (type) {
    case PlyType::kInt8:
      return "char";
    case PlyType::kUint8:
      return "uchar";
    case PlyType::kInt16:
      return "short";
    case PlyType::kUint16:
      return "ushort";
    case PlyType::kInt32:
      return "int";
    case PlyType::kUint32:
      return "uint";
    case PlyType::kFloat32:
      return "float";
    case PlyType::kFloat64:
      return "double";
  }
  return "?";
}

struct PlyProperty {
  std::string name;
  PlyType type = PlyType::kFloat32;  // the item type for lists
  bool is_list = false;
  PlyType count_type = PlyType::kUint8;
};

struct PlyElement {
  std::string name;
  uint64_t count = 0;
  std::vector<PlyProperty> properties;
};

enum class Encoding { kAscii, kLittle, kBig };

struct PlyHeader {
  Encoding encoding = Encoding::kAscii;
  std::vector<PlyElement> elements;
  size_t body_offset = 0;
  // Range-grid size from 'obj_info num_cols N' / 'obj_info num_rows N' (or the same as comments); -1: absent.
  int64_t num_cols = -1;
  int64_t num_rows = -1;
};

// Reads 'num_cols N' or 'num_rows N' after an obj_info or comment keyword.
void ReadGridSize(const std::vector<std::string_view>& words, PlyHeader* header) {
  if (words.size() != 3) return;
  int64_t* target = words[1] == "num_cols" ? &header->num_cols : words[1] == "num_rows" ? &header->num_rows : nullptr;
  if (target == nullptr) return;
  int64_t value = -1;
  const auto [ptr, ec] = std::from_chars(words[2].data(), words[2].data() + words[2].size(), value);
  if (ec == std::errc() && ptr == words[2].data() + words[2].size() && value > 0) *target = value;
}

std::vector<std::string_view> SplitWords(std::string_view line) {
  std::vector<std::string_view> words;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && TextCursor::IsSpace(line[i])) ++i;
    const size_t start = i;
    while (i < line.size() && !TextCursor::IsSpace(line[i])) ++i;
    if (i > start) words.push_back(line.substr(start, i - start));
  }
  return words;
}

PlyHeader ParseHeader(std::string_view bytes, const std::string& name) {
  RB_CHECK(!bytes.empty(), name, ": empty file");
  RB_CHECK(bytes.size() >= 4 && bytes.substr(0, 3) == "ply" && (bytes[3] == '\n' || bytes[3] == '\r'), name,
           ": not a PLY file (it must start with the line 'ply')");
  TextCursor cursor(bytes.data(), bytes.data() + bytes.size());
  cursor.ReadLine();
  PlyHeader header;
  bool have_format = false;
  bool ended = false;
  while (!cursor.AtEnd()) {
    const int64_t line_number = cursor.line();
    const std::string_view line = cursor.ReadLine();
    const std::vector<std::string_view> words = SplitWords(line);
    if (words.empty()) continue;
    const std::string_view key = words[0];
    if (key == "end_header") {
      ended = true;
      break;
    }
    if (key == "comment" || key == "obj_info") {
      ReadGridSize(words, &header);
      continue;
    }
    if (key == "format") {
      RB_CHECK(words.size() >= 2, name, ": header line ", line_number, ": 'format' needs an encoding");
      if (words[1] == "ascii") {
        header.encoding = Encoding::kAscii;
      } else if (words[1] == "binary_little_endian") {
        header.encoding = Encoding::kLittle;
      } else if (words[1] == "binary_big_endian") {
        header.encoding = Encoding::kBig;
      } else {
        RB_FAIL(name, ": header line ", line_number, ": unknown format '", words[1], "'");
      }
      have_format = true;
      continue;
    }
    if (key == "element") {
      RB_CHECK(words.size() == 3, name, ": header line ", line_number, ": expected 'element NAME COUNT'");
      PlyElement element;
      element.name = std::string(words[1]);
      const std::string_view count = words[2];
      const auto [ptr, ec] = std::from_chars(count.data(), count.data() + count.size(), element.count);
      RB_CHECK(ec == std::errc() && ptr == count.data() + count.size(), name, ": header line ", line_number,
               ": element count '", count, "' is not a non-negative integer");
      header.elements.push_back(std::move(element));
      continue;
    }
    if (key == "property") {
      RB_CHECK(!header.elements.empty(), name, ": header line ", line_number, ": property before any element");
      PlyProperty property;
      if (words.size() == 5 && words[1] == "list") {
        property.is_list = true;
        RB_CHECK(ParseType(words[2], &property.count_type) && IsInteger(property.count_type), name,
                 ": header line ", line_number, ": list count type '", words[2], "' is not an integer type");
        RB_CHECK(ParseType(words[3], &property.type), name, ": header line ", line_number, ": unknown type '",
                 words[3], "'");
        property.name = std::string(words[4]);
      } else {
        RB_CHECK(words.size() == 3, name, ": header line ", line_number,
                 ": expected 'property TYPE NAME' or 'property list COUNT_TYPE TYPE NAME'");
        RB_CHECK(ParseType(words[1], &property.type), name, ": header line ", line_number, ": unknown type '",
                 words[1], "'");
        property.name = std::string(words[2]);
      }
      header.elements.back().properties.push_back(std::move(property));
      continue;
    }
    RB_FAIL(name, ": header line ", line_number, ": unknown keyword '", key, "'");
  }
  RB_CHECK(ended, name, ": truncated header (no 'end_header' line)");
  RB_CHECK(have_format, name, ": header has no 'format' line");
  header.body_offset = static_cast<size_t>(cursor.position() - bytes.data());
  return header;
}

// What the reader does with each property of the vertex and face elements.
enum Slot : int {
  kX, kY, kZ, kNx, kNy, kNz, kCovXX, kCovXY, kCovXZ, kCovYY, kCovYZ, kCovZZ, kPixelU, kPixelV, kNumSlots,
  kSkip = -1
};

int VertexSlot(std::string_view name) {
  static constexpr std::string_view kNames[kNumSlots] = {"x",      "y",      "z",      "nx",     "ny",
                                                         "nz",     "cov_xx", "cov_xy", "cov_xz", "cov_yy",
                                                         "cov_yz", "cov_zz", "pixel_u", "pixel_v"};
  for (int s = 0; s < kNumSlots; ++s) {
    if (kNames[s] == name) return s;
  }
  return kSkip;
}

template <typename U>
U Swap(U u) {
  if constexpr (sizeof(U) == 2) return __builtin_bswap16(u);
  if constexpr (sizeof(U) == 4) return __builtin_bswap32(u);
  if constexpr (sizeof(U) == 8) return __builtin_bswap64(u);
  return u;
}

template <typename T>
T Load(const char* p, bool swap) {
  if constexpr (sizeof(T) == 1) {
    T value;
    std::memcpy(&value, p, 1);
    return value;
  } else {
    using U = std::conditional_t<sizeof(T) == 2, uint16_t, std::conditional_t<sizeof(T) == 4, uint32_t, uint64_t>>;
    U u;
    std::memcpy(&u, p, sizeof(U));
    if (swap) u = Swap(u);
    T value;
    std::memcpy(&value, &u, sizeof(T));
    return value;
  }
}

// The value at p as type `type` (a little- or big-endian scalar of that PLY type), handed to f as its C++ type.
template <typename F>
auto LoadAs(PlyType type, const char* p, bool swap, F&& f) {
  switch (type) {
    case PlyType::kInt8:
      return f(Load<int8_t>(p, swap));
    case PlyType::kUint8:
      return f(Load<uint8_t>(p, swap));
    case PlyType::kInt16:
      return f(Load<int16_t>(p, swap));
    case PlyType::kUint16:
      return f(Load<uint16_t>(p, swap));
    case PlyType::kInt32:
      return f(Load<int32_t>(p, swap));
    case PlyType::kUint32:
      return f(Load<uint32_t>(p, swap));
    case PlyType::kFloat32:
      return f(Load<float>(p, swap));
    case PlyType::kFloat64:
      break;
  }
  return f(Load<double>(p, swap));
}

double LoadDouble(PlyType type, const char* p, bool swap) {
  return LoadAs(type, p, swap, [](auto value) { return static_cast<double>(value); });
}

// Integer types only (checked in the header); −1 for the others.
int64_t LoadInt(PlyType type, const char* p, bool swap) {
  return LoadAs(type, p, swap, [](auto value) -> int64_t {
    if constexpr (std::is_floating_point_v<decltype(value)>) {
      return -1;
    } else {
      return static_cast<int64_t>(value);
    }
  });
}

// Reads the body, one element at a time, into the mesh.
class BodyReader {
 public:
  BodyReader(std::string_view bytes, const PlyHeader& header, const std::string& name, MeshReadSummary* summary,
             PlyRangeGrid* grid = nullptr)
      : grid_(grid),
        header_(header),
        name_(name),
        summary_(summary),
        p_(bytes.data() + header.body_offset),
        end_(bytes.data() + bytes.size()),
        text_(p_, end_, 1 + std::count(bytes.data(), bytes.data() + header.body_offset, '\n')),
        swap_((header.encoding == Encoding::kBig) == (std::endian::native == std::endian::little)) {}

  NoisyMesh Read() {
    bool have_vertices = false;
    bool have_faces = false;
    for (const PlyElement& element : header_.elements) {
      if (element.name == "vertex" && !have_vertices) {
        ReadVertices(element);
        have_vertices = true;
      } else if (element.name == "face" && !have_faces) {
        ReadFaces(element);
        have_faces = true;
      } else if (element.name == "range_grid" && grid_ != nullptr && grid_->cell_vertex.empty()) {
        ReadRangeGrid(element);
      } else if (element.name == "tristrips" && element.properties.size() == 1 && element.properties[0].is_list &&
                 element.properties[0].name == "vertex_indices" && IsInteger(element.properties[0].type)) {
        ReadTriangleStrips(element);
      } else {
        SkipElement(element);
        if (element.count > 0) {
          summary_->notices.push_back(StrCat("skipped ", element.count, " '", element.name, "' elements"));
        }
      }
    }
    RB_CHECK(have_vertices, name_, ": no 'vertex' element in the header");
    if (header_.encoding == Encoding::kAscii) {
      text_.SkipWhitespace();
      RB_CHECK(text_.AtEnd(), name_, ": more data after the last element than the header declares (line ",
               text_.line(), ")");
    } else if (p_ < end_) {
      summary_->notices.push_back(StrCat("ignored ", end_ - p_, " bytes after the last element"));
    }
    splitter_.Finish(mesh_.mesh.V, &triangles_, nullptr, summary_);
    mesh_.mesh.F = Faces(static_cast<Eigen::Index>(triangles_.size() / 3), 3);
    if (!triangles_.empty()) std::memcpy(mesh_.mesh.F.data(), triangles_.data(), triangles_.size() * sizeof(int));
    try {
      CheckFaceIndices(mesh_.mesh.F, mesh_.mesh.V.rows(), "face");
    } catch (const Error& e) {
      // Triangle numbers differ from file face numbers only when polygons were split.
      RB_FAIL(name_, ": ", e.what(), splitter_.count() > 0 ? " (counting triangles after splitting polygons)" : "");
    }
    return std::move(mesh_);
  }

 private:
  bool ascii() const { return header_.encoding == Encoding::kAscii; }

  // The fewest bytes one element can take: the bound that keeps absurd counts from allocating.
  // `min_list` is the shortest length of list property `list` (faces need 3 indices); other lists may be empty.
  uint64_t MinBytes(const PlyElement& element, int list = -1, int min_list = 0) const {
    uint64_t bytes = 0;
    for (size_t k = 0; k < element.properties.size(); ++k) {
      const PlyProperty& property = element.properties[k];
      const bool face_list = static_cast<int>(k) == list;
      const int min_face_list = face_list ? min_list : 0;
      if (ascii()) {
        bytes += 2 * (property.is_list ? 1 + (face_list ? min_face_list : 0) : 1);  // value + separator
      } else if (property.is_list) {
        bytes += SizeOf(property.count_type) + (face_list ? min_face_list * SizeOf(property.type) : 0);
      } else {
        bytes += SizeOf(property.type);
      }
    }
    return bytes;
  }

  void CheckCount(const PlyElement& element, uint64_t min_bytes) {
    if (element.count == 0 || min_bytes == 0) return;
    const uint64_t remaining = static_cast<uint64_t>(end_ - (ascii() ? text_.position() : p_));
    // +1: the last ascii value needs no separator.
    const uint64_t fit = (remaining + (ascii() ? 1 : 0)) / min_bytes;
    RB_CHECK(element.count <= fit, name_, ": header declares ", element.count, " '", element.name,
             "' elements but only ", remaining, " bytes follow (room for at most ", fit,
             "): truncated file or wrong count");
  }

  [[noreturn]] void Truncated(const PlyElement& element, uint64_t index) const {
    RB_FAIL(name_, ": truncated: file ends in '", element.name, "' element ", index, " of ", element.count);
  }

  // Binary: pointer to `size` bytes, advancing. Ascii callers use the text helpers instead.
  const char* Take(int size, const PlyElement& element, uint64_t index) {
    if (end_ - p_ < size) Truncated(element, index);
    const char* at = p_;
    p_ += size;
    return at;
  }

  // A value of the declared `type`: one that the type cannot hold (300 for a uchar, 1.5 for an int, 1e39 for a
  // float) is refused, since every reader that honours the header would read another number.
  double TextDouble(const PlyElement& element, uint64_t index, const PlyProperty& property, PlyType type) {
    text_.SkipWhitespace();
    if (text_.AtEnd()) Truncated(element, index);
    double value = 0;
    if (!text_.ParseDouble(&value)) BadText(element, index, property, "a number");
    if (!FitsType(value, type)) BadValue(element, index, property, type);
    return value;
  }

  int64_t TextInt(const PlyElement& element, uint64_t index, const PlyProperty& property, PlyType type) {
    text_.SkipWhitespace();
    if (text_.AtEnd()) Truncated(element, index);
    int64_t value = 0;
    if (!text_.ParseInt(&value)) BadText(element, index, property, "an integer");
    if (!FitsType(static_cast<double>(value), type)) BadValue(element, index, property, type);
    return value;
  }

  [[noreturn]] void BadText(const PlyElement& element, uint64_t index, const PlyProperty& property,
                            const char* expected) {
    const std::string_view word = text_.Word();
    RB_FAIL(name_, ": line ", text_.line(), ": '", element.name, "' element ", index, " property '",
            property.name, "': expected ", expected, ", found '", word.substr(0, 40), "'");
  }

  // The value just read (the word before the text position) does not fit `type`.
  [[noreturn]] void BadValue(const PlyElement& element, uint64_t index, const PlyProperty& property, PlyType type) {
    RB_FAIL(name_, ": line ", text_.line(), ": '", element.name, "' element ", index, " property '", property.name,
            "': value out of range for its declared type ", TypeName(type));
  }

  // A scalar value of any type as a double.
  double ScalarDouble(const PlyElement& element, uint64_t index, const PlyProperty& property) {
    if (ascii()) return TextDouble(element, index, property, property.type);
    return LoadDouble(property.type, Take(SizeOf(property.type), element, index), swap_);
  }

  int64_t ListCount(const PlyElement& element, uint64_t index, const PlyProperty& property) {
    int64_t count = 0;
    if (ascii()) {
      count = TextInt(element, index, property, property.count_type);
    } else {
      count = LoadInt(property.count_type, Take(SizeOf(property.count_type), element, index), swap_);
    }
    RB_CHECK(count >= 0, name_, ": '", element.name, "' element ", index, " property '", property.name,
             "': negative list length ", count);
    return count;
  }

  void SkipValue(const PlyElement& element, uint64_t index, const PlyProperty& property, PlyType type) {
    if (ascii()) {
      TextDouble(element, index, property, type);
    } else {
      Take(SizeOf(type), element, index);
    }
  }

  void SkipProperty(const PlyElement& element, uint64_t index, const PlyProperty& property) {
    if (!property.is_list) {
      SkipValue(element, index, property, property.type);
      return;
    }
    const int64_t count = ListCount(element, index, property);
    if (!ascii()) {
      const uint64_t bytes = static_cast<uint64_t>(count) * SizeOf(property.type);
      if (bytes > static_cast<uint64_t>(end_ - p_)) Truncated(element, index);
      p_ += bytes;
      return;
    }
    for (int64_t i = 0; i < count; ++i) SkipValue(element, index, property, property.type);
  }

  void SkipElement(const PlyElement& element) {
    CheckCount(element, MinBytes(element));
    if (element.properties.empty()) return;
    bool fixed = !ascii();
    uint64_t stride = 0;
    for (const PlyProperty& property : element.properties) {
      fixed = fixed && !property.is_list;
      stride += SizeOf(property.type);
    }
    if (fixed) {
      p_ += element.count * stride;  // CheckCount bounded count * stride by the bytes left
      return;
    }
    for (uint64_t i = 0; i < element.count; ++i) {
      for (const PlyProperty& property : element.properties) SkipProperty(element, i, property);
    }
  }

  void ReadVertices(const PlyElement& element) {
    std::vector<int> slots;
    int have[kNumSlots] = {};
    std::vector<std::string> skipped;
    for (const PlyProperty& property : element.properties) {
      int slot = VertexSlot(property.name);
      if (slot != kSkip && (property.is_list || have[slot])) slot = kSkip;
      if (slot != kSkip) have[slot] = 1;
      if (slot == kSkip) skipped.push_back(property.name);
      slots.push_back(slot);
    }
    RB_CHECK(have[kX] && have[kY] && have[kZ], name_, ": 'vertex' element lacks scalar x, y and z properties");
    const bool normals = have[kNx] && have[kNy] && have[kNz];
    const bool covariance = have[kCovXX] && have[kCovXY] && have[kCovXZ] && have[kCovYY] && have[kCovYZ] &&
                            have[kCovZZ];
    const bool pixel = have[kPixelU] && have[kPixelV];
    if (!normals && (have[kNx] || have[kNy] || have[kNz])) {
      summary_->notices.push_back("ignored incomplete vertex normals (need nx, ny and nz)");
    }
    if (!covariance && (have[kCovXX] || have[kCovXY] || have[kCovXZ] || have[kCovYY] || have[kCovYZ] ||
                        have[kCovZZ])) {
      summary_->notices.push_back("ignored incomplete covariance (need cov_xx cov_xy cov_xz cov_yy cov_yz cov_zz)");
    }
    if (!pixel && (have[kPixelU] || have[kPixelV])) {
      summary_->notices.push_back("ignored incomplete pixel position (need pixel_u and pixel_v)");
    }
    if (!skipped.empty()) {
      std::string list;
      for (const std::string& s : skipped) list += (list.empty() ? "" : " ") + s;
      summary_->notices.push_back("skipped vertex properties: " + list);
    }
    CheckCount(element, MinBytes(element));
    RB_CHECK(element.count <= static_cast<uint64_t>(std::numeric_limits<int>::max()), name_, ": ", element.count,
             " vertices are more than this program supports");
    const auto n = static_cast<Eigen::Index>(element.count);
    Mesh& mesh = mesh_.mesh;
    mesh.V.resize(n, 3);
    if (normals) mesh.N.resize(n, 3);
    if (covariance) mesh_.covariance.resize(static_cast<size_t>(n));
    if (pixel) mesh_.pixel.resize(n, 2);

    double values[kNumSlots] = {};
    for (Eigen::Index i = 0; i < n; ++i) {
      const auto index = static_cast<uint64_t>(i);
      for (size_t k = 0; k < slots.size(); ++k) {
        const PlyProperty& property = element.properties[k];
        if (slots[k] == kSkip) {
          SkipProperty(element, index, property);
        } else {
          values[slots[k]] = ScalarDouble(element, index, property);
        }
      }
      mesh.V.row(i) << values[kX], values[kY], values[kZ];
      if (normals) mesh.N.row(i) << values[kNx], values[kNy], values[kNz];
      if (covariance) {
        Eigen::Matrix3d& c = mesh_.covariance[static_cast<size_t>(i)];
        c << values[kCovXX], values[kCovXY], values[kCovXZ],  //
            values[kCovXY], values[kCovYY], values[kCovYZ],   //
            values[kCovXZ], values[kCovYZ], values[kCovZZ];
      }
      if (pixel) {
        mesh_.pixel.row(i) << static_cast<float>(values[kPixelU]), static_cast<float>(values[kPixelV]);
      }
    }
  }

  int64_t FaceIndex(const PlyElement& element, uint64_t index, const PlyProperty& property) {
    int64_t value = 0;
    if (ascii()) {
      value = TextInt(element, index, property, property.type);
    } else {
      value = LoadInt(property.type, Take(SizeOf(property.type), element, index), swap_);
    }
    RB_CHECK(value >= 0 && value < std::numeric_limits<int>::max(), name_, ": face ", index,
             " has vertex index ", value, " (out of range)");
    return value;
  }

  void ReadFaces(const PlyElement& element) {
    int list = -1;
    for (size_t k = 0; k < element.properties.size(); ++k) {
      const PlyProperty& property = element.properties[k];
      if (property.is_list && (property.name == "vertex_indices" || property.name == "vertex_index") &&
          list < 0) {
        RB_CHECK(IsInteger(property.type), name_, ": face property '", property.name,
                 "' must hold integers");
        list = static_cast<int>(k);
      }
    }
    RB_CHECK(list >= 0 || element.count == 0, name_,
             ": 'face' element lacks a 'vertex_indices' list property");
    if (element.properties.size() > 1) {
      std::string names;
      for (size_t k = 0; k < element.properties.size(); ++k) {
        if (static_cast<int>(k) != list) names += (names.empty() ? "" : " ") + element.properties[k].name;
      }
      summary_->notices.push_back("skipped face properties: " + names);
    }
    CheckCount(element, MinBytes(element, list, 3));
    RB_CHECK(element.count <= static_cast<uint64_t>(std::numeric_limits<int>::max() / 3), name_, ": ",
             element.count, " faces are more than this program supports");
    triangles_.reserve(3 * element.count);
    const PlyProperty* face_list = list >= 0 ? &element.properties[static_cast<size_t>(list)] : nullptr;
    // The common binary layout (one list of uchar count and int indices, file and host byte order alike)
    // takes a memcpy per face.
    const bool fast = !ascii() && !swap_ && element.properties.size() == 1 && face_list != nullptr &&
                      face_list->count_type == PlyType::kUint8 &&
                      (face_list->type == PlyType::kInt32 || face_list->type == PlyType::kUint32);
    std::vector<int> polygon;
    for (uint64_t f = 0; f < element.count; ++f) {
      if (fast && end_ - p_ >= 13 && static_cast<unsigned char>(*p_) == 3) {
        int tri[3];
        std::memcpy(tri, p_ + 1, sizeof(tri));
        RB_CHECK(tri[0] >= 0 && tri[1] >= 0 && tri[2] >= 0, name_, ": face ", f, " has a negative vertex index");
        triangles_.insert(triangles_.end(), tri, tri + 3);
        p_ += 13;
        continue;
      }
      for (size_t k = 0; k < element.properties.size(); ++k) {
        const PlyProperty& property = element.properties[k];
        if (static_cast<int>(k) != list) {
          SkipProperty(element, f, property);
          continue;
        }
        const int64_t count = ListCount(element, f, property);
        RB_CHECK(count >= 3, name_, ": face ", f, " has ", count, " vertices (at least 3 needed)");
        // Each index takes at least one byte (two in ascii), so this bounds the allocation below.
        if (static_cast<uint64_t>(count) > static_cast<uint64_t>(end_ - (ascii() ? text_.position() : p_))) {
          Truncated(element, f);
        }
        polygon.resize(static_cast<size_t>(count));
        for (int64_t c = 0; c < count; ++c)
          polygon[static_cast<size_t>(c)] = static_cast<int>(FaceIndex(element, f, property));
        RB_CHECK(triangles_.size() / 3 + static_cast<size_t>(count - 2) <=
                     static_cast<size_t>(std::numeric_limits<int>::max() / 3),
                 name_, ": too many triangles");
        if (count > 3) {
          splitter_.Add(polygon.data(), nullptr, polygon.size(), &triangles_, nullptr, mesh_.mesh.V.data(),
                        static_cast<size_t>(mesh_.mesh.V.rows()));
        } else {
          triangles_.insert(triangles_.end(), polygon.begin(), polygon.end());
        }
      }
    }
  }

  // element tristrips (as the Stanford repository's and Open Inventor's exporters write): each list holds strips
  // separated by -1; triangle k of a strip is (v_k, v_k+1, v_k+2), its first two swapped at odd k so that all
  // keep one orientation; triangles with a repeated vertex (the joins of strips) are left out. They follow the
  // file's faces.
  void ReadTriangleStrips(const PlyElement& element) {
    const PlyProperty& property = element.properties[0];
    CheckCount(element, MinBytes(element));
    std::vector<int64_t> strip;
    int64_t strips = 0;
    const size_t before = triangles_.size();
    const auto flush = [&] {
      for (size_t k = 0; k + 2 < strip.size(); ++k) {
        int64_t a = strip[k], b = strip[k + 1];
        const int64_t c = strip[k + 2];
        if (a == b || b == c || a == c) continue;
        if (k % 2 == 1) std::swap(a, b);
        RB_CHECK(triangles_.size() / 3 < static_cast<size_t>(std::numeric_limits<int>::max() / 3), name_,
                 ": too many triangles");
        triangles_.insert(triangles_.end(), {static_cast<int>(a), static_cast<int>(b), static_cast<int>(c)});
      }
      if (strip.size() >= 3) ++strips;
      strip.clear();
    };
    for (uint64_t e = 0; e < element.count; ++e) {
      const int64_t count = ListCount(element, e, property);
      if (!ascii() && static_cast<uint64_t>(count) * SizeOf(property.type) > static_cast<uint64_t>(end_ - p_)) {
        Truncated(element, e);
      }
      for (int64_t i = 0; i < count; ++i) {
        const int64_t v = ascii() ? TextInt(element, e, property, property.type)
                                  : LoadInt(property.type, Take(SizeOf(property.type), element, e), swap_);
        if (v == -1 || (property.type == PlyType::kUint32 && v == 0xffffffffLL)) {
          flush();
          continue;
        }
        RB_CHECK(v >= 0 && v < std::numeric_limits<int>::max(), name_, ": tristrips element ", e, " has vertex index ",
                 v, " (out of range)");
        strip.push_back(v);
      }
      flush();
    }
    summary_->notices.push_back(StrCat("read ", (triangles_.size() - before) / 3, " triangles from ", strips,
                                       " triangle strips ('tristrips')"));
  }

  // element range_grid: one list of 0 or 1 vertex indices per cell, row by row (num_cols cells a row).
  void ReadRangeGrid(const PlyElement& element) {
    RB_CHECK(element.properties.size() == 1 && element.properties[0].is_list &&
                 IsInteger(element.properties[0].type),
             name_, ": 'range_grid' element must have one integer list property (its vertex indices)");
    RB_CHECK(header_.num_cols > 0 && header_.num_rows > 0, name_,
             ": 'range_grid' without its size (header lines 'obj_info num_cols N' and 'obj_info num_rows N')");
    RB_CHECK(header_.num_cols <= std::numeric_limits<int>::max() && header_.num_rows <= std::numeric_limits<int>::max(),
             name_, ": 'range_grid' of ", header_.num_cols, " x ", header_.num_rows, " cells is too large");
    // Both below 2^31: their product cannot wrap in 64 bits (a wrapped product passed this check and the grid
    // was read far outside its cells).
    RB_CHECK(static_cast<uint64_t>(header_.num_cols) * static_cast<uint64_t>(header_.num_rows) == element.count,
             name_, ": 'range_grid' has ", element.count, " cells but num_cols x num_rows is ", header_.num_cols,
             " x ", header_.num_rows);
    CheckCount(element, MinBytes(element));
    const int64_t num_vertices = mesh_.mesh.V.rows();
    const PlyProperty& property = element.properties[0];
    grid_->width = static_cast<int>(header_.num_cols);
    grid_->height = static_cast<int>(header_.num_rows);
    grid_->cell_vertex.assign(static_cast<size_t>(element.count), -1);
    for (uint64_t c = 0; c < element.count; ++c) {
      const int64_t count = ListCount(element, c, property);
      RB_CHECK(count <= 1, name_, ": range_grid cell ", c, " lists ", count, " vertices (0 or 1 expected)");
      if (count == 0) continue;
      const int64_t v = FaceIndex(element, c, property);
      RB_CHECK(v < num_vertices, name_, ": range_grid cell ", c, " names vertex ", v, " of ", num_vertices);
      grid_->cell_vertex[static_cast<size_t>(c)] = static_cast<int>(v);
    }
  }

  PlyRangeGrid* grid_;
  const PlyHeader& header_;
  const std::string& name_;
  MeshReadSummary* summary_;
  const char* p_;
  const char* end_;
  TextCursor text_;
  bool swap_;
  NoisyMesh mesh_;
  std::vector<int> triangles_;
  PolygonSplitter splitter_;
};

// Output with the byte order of the file.
class Sink {
 public:
  Sink(std::string* out, PlyEncoding encoding, int precision)
      : out_(out),
        ascii_(encoding == PlyEncoding::kAscii),
        swap_((encoding == PlyEncoding::kBinaryBigEndian) == (std::endian::native == std::endian::little)),
        precision_(precision) {}

  bool ascii() const { return ascii_; }

  template <typename T>
  void Put(T value) {
    if (ascii_) {
      if (!at_line_start_) out_->push_back(' ');
      at_line_start_ = false;
      if constexpr (std::is_floating_point_v<T>) {
        AppendDouble(out_, value, std::is_same_v<T, float> ? std::min(precision_, 9) : precision_);
      } else {
        AppendInt(out_, value);
      }
      return;
    }
    if constexpr (sizeof(T) == 1) {
      out_->push_back(static_cast<char>(value));
    } else {
      using U = std::conditional_t<sizeof(T) == 2, uint16_t, std::conditional_t<sizeof(T) == 4, uint32_t, uint64_t>>;
      U u;
      std::memcpy(&u, &value, sizeof(U));
      if (swap_) u = Swap(u);
      char bytes[sizeof(U)];
      std::memcpy(bytes, &u, sizeof(U));
      out_->append(bytes, sizeof(U));
    }
  }

  void EndElement() {
    if (ascii_) {
      out_->push_back('\n');
      at_line_start_ = true;
    }
  }

 private:
  std::string* out_;
  bool ascii_;
  bool swap_;
  int precision_;
  bool at_line_start_ = true;
};

const char* FormatLine(PlyEncoding encoding) {
  switch (encoding) {
    case PlyEncoding::kAscii:
      return "format ascii 1.0\n";
    case PlyEncoding::kBinaryBigEndian:
      return "format binary_big_endian 1.0\n";
    case PlyEncoding::kBinaryLittleEndian:
      break;
  }
  return "format binary_little_endian 1.0\n";
}

}  // namespace

NoisyMesh ParsePly(std::string_view bytes, const std::string& name, MeshReadSummary* summary,
                   PlyRangeGrid* grid) {
  const PlyHeader header = ParseHeader(bytes, name);
  BodyReader reader(bytes, header, name, summary, grid);
  return reader.Read();
}

std::string FormatPly(const NoisyMesh& noisy, const MeshWriteOptions& options) {
  const Mesh& mesh = noisy.mesh;
  const bool normals = options.write_vertex_normals && mesh.N.rows() == mesh.V.rows() && mesh.V.rows() > 0;
  const bool covariance = !noisy.covariance.empty();
  const bool pixel = noisy.pixel.rows() > 0;
  const bool corner = !options.corner_normals.empty();
  std::string out;
  out += "ply\n";
  out += FormatLine(options.ply_encoding);
  out += "comment written by rangebayes\n";
  out += StrCat("element vertex ", mesh.V.rows(), "\n");
  out += "property double x\nproperty double y\nproperty double z\n";
  if (normals) out += "property double nx\nproperty double ny\nproperty double nz\n";
  if (covariance) {
    out +=
        "property double cov_xx\nproperty double cov_xy\nproperty double cov_xz\n"
        "property double cov_yy\nproperty double cov_yz\nproperty double cov_zz\n";
  }
  if (pixel) out += "property float pixel_u\nproperty float pixel_v\n";
  out += StrCat("element face ", mesh.F.rows(), "\n");
  out += "property list uchar int vertex_indices\n";
  // Corner normals as a face property: nine values per face, corner 0 first.
  if (corner) out += "property list uchar double corner_normals\n";
  out += "end_header\n";

  const bool ascii = options.ply_encoding == PlyEncoding::kAscii;
  const size_t vertex_bytes = 8 * (3 + (normals ? 3 : 0) + (covariance ? 6 : 0)) + (pixel ? 8 : 0);
  const size_t face_bytes = 13 + (corner ? 73 : 0);
  const size_t binary_size = vertex_bytes * static_cast<size_t>(mesh.V.rows()) +
                             face_bytes * static_cast<size_t>(mesh.F.rows());
  out.reserve(out.size() + (ascii ? 2 * binary_size : binary_size));
  Sink sink(&out, options.ply_encoding, options.precision);
  for (Eigen::Index i = 0; i < mesh.V.rows(); ++i) {
    sink.Put(mesh.V(i, 0));
    sink.Put(mesh.V(i, 1));
    sink.Put(mesh.V(i, 2));
    if (normals) {
      sink.Put(mesh.N(i, 0));
      sink.Put(mesh.N(i, 1));
      sink.Put(mesh.N(i, 2));
    }
    if (covariance) {
      const Eigen::Matrix3d& c = noisy.covariance[static_cast<size_t>(i)];
      sink.Put(c(0, 0));
      sink.Put(c(0, 1));
      sink.Put(c(0, 2));
      sink.Put(c(1, 1));
      sink.Put(c(1, 2));
      sink.Put(c(2, 2));
    }
    if (pixel) {
      sink.Put(noisy.pixel(i, 0));
      sink.Put(noisy.pixel(i, 1));
    }
    sink.EndElement();
  }
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
    sink.Put(static_cast<uint8_t>(3));
    sink.Put(static_cast<int32_t>(mesh.F(f, 0)));
    sink.Put(static_cast<int32_t>(mesh.F(f, 1)));
    sink.Put(static_cast<int32_t>(mesh.F(f, 2)));
    if (corner) {
      sink.Put(static_cast<uint8_t>(9));
      for (int k = 0; k < 3; ++k) {
        const int n = options.corner_normals.normal_index(f, k);
        for (int d = 0; d < 3; ++d) sink.Put(options.corner_normals.normals(n, d));
      }
    }
    sink.EndElement();
  }
  return out;
}

std::string FormatPolygonPly(const Vertices& V, const std::vector<std::vector<int>>& polygons,
                             const MeshWriteOptions& options) {
  size_t largest = 0;
  size_t total = 0;
  for (const auto& polygon : polygons) {
    largest = std::max(largest, polygon.size());
    total += polygon.size();
  }
  const bool wide = largest > 255;
  std::string out;
  out += "ply\n";
  out += FormatLine(options.ply_encoding);
  out += "comment written by rangebayes\n";
  out += StrCat("element vertex ", V.rows(), "\n");
  out += "property double x\nproperty double y\nproperty double z\n";
  out += StrCat("element face ", polygons.size(), "\n");
  out += wide ? "property list int int vertex_indices\n" : "property list uchar int vertex_indices\n";
  out += "end_header\n";
  out.reserve(out.size() + 24 * static_cast<size_t>(V.rows()) + 4 * (total + polygons.size()));
  Sink sink(&out, options.ply_encoding, options.precision);
  for (Eigen::Index i = 0; i < V.rows(); ++i) {
    sink.Put(V(i, 0));
    sink.Put(V(i, 1));
    sink.Put(V(i, 2));
    sink.EndElement();
  }
  for (const auto& polygon : polygons) {
    if (wide) {
      sink.Put(static_cast<int32_t>(polygon.size()));
    } else {
      sink.Put(static_cast<uint8_t>(polygon.size()));
    }
    for (const int v : polygon) sink.Put(static_cast<int32_t>(v));
    sink.EndElement();
  }
  return out;
}

}  // namespace rangebayes::mesh_io

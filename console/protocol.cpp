#include "console/protocol.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <unordered_map>

#include "core/error.h"
#include "core/json_text.h"

namespace rangebayes {
namespace {

void PutU32(std::string* out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out->push_back(static_cast<char>((v >> (8 * i)) & 0xffu));
}

std::uint32_t GetU32(std::string_view s, size_t at) {
  std::uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v |= static_cast<std::uint32_t>(static_cast<unsigned char>(s[at + i])) << (8 * i);
  return v;
}

}  // namespace

std::string EncodeConsoleMessage(ConsoleMessageType type, const nlohmann::json& header, std::string_view payload) {
  const std::string h = JsonText(header);
  std::string out;
  out.reserve(8 + h.size() + 3 + payload.size());
  out.push_back(static_cast<char>(type));
  out.append(3, '\0');
  PutU32(&out, static_cast<std::uint32_t>(h.size()));
  out += h;
  while (out.size() % 4 != 0) out.push_back('\0');
  out.append(payload.data(), payload.size());
  return out;
}

ConsoleMessage DecodeConsoleMessage(std::string_view message) {
  RB_CHECK(message.size() >= 8, "console message: ", message.size(), " bytes, shorter than its 8-byte prefix");
  const auto type = static_cast<std::uint8_t>(message[0]);
  RB_CHECK(type == 1 || type == 2, "console message: unknown type ", static_cast<int>(type));
  const std::uint32_t n = GetU32(message, 4);
  RB_CHECK(n <= message.size() - 8, "console message: header of ", n, " bytes in a ", message.size(),
           "-byte message");
  ConsoleMessage m;
  m.type = static_cast<ConsoleMessageType>(type);
  m.header = nlohmann::json::parse(message.substr(8, n), nullptr, /*allow_exceptions=*/false);
  RB_CHECK(!m.header.is_discarded() && m.header.is_object(), "console message: header is not a JSON object");
  size_t start = 8 + n;
  start = (start + 3) / 4 * 4;
  RB_CHECK(start <= message.size(), "console message: truncated after its header");
  m.payload = message.substr(start);
  return m;
}

std::string EncodeMeshPayload(const Mesh& mesh) {
  std::string out;
  const size_t nv = static_cast<size_t>(mesh.num_vertices());
  const size_t nf = static_cast<size_t>(mesh.num_faces());
  out.reserve(8 + 12 * (nv + nf));
  PutU32(&out, static_cast<std::uint32_t>(nv));
  PutU32(&out, static_cast<std::uint32_t>(nf));
  const size_t positions_at = out.size();
  out.resize(positions_at + 12 * nv + 12 * nf);
  char* p = out.data() + positions_at;
  for (size_t i = 0; i < nv; ++i) {
    for (int c = 0; c < 3; ++c) {
      const float v = static_cast<float>(mesh.V(static_cast<Eigen::Index>(i), c));
      std::memcpy(p, &v, 4);  // little-endian hosts only (x86-64, aarch64)
      p += 4;
    }
  }
  for (size_t f = 0; f < nf; ++f) {
    for (int c = 0; c < 3; ++c) {
      const auto v = static_cast<std::uint32_t>(mesh.F(static_cast<Eigen::Index>(f), c));
      std::memcpy(p, &v, 4);
      p += 4;
    }
  }
  return out;
}

Mesh DecodeMeshPayload(std::string_view payload) {
  RB_CHECK(payload.size() >= 8, "mesh payload: ", payload.size(), " bytes, shorter than its counts");
  const std::uint64_t nv = GetU32(payload, 0);
  const std::uint64_t nf = GetU32(payload, 4);
  RB_CHECK(payload.size() == 8 + 12 * nv + 12 * nf, "mesh payload: ", payload.size(), " bytes for ", nv,
           " vertices and ", nf, " faces");
  Mesh m;
  m.V.resize(static_cast<Eigen::Index>(nv), 3);
  m.F.resize(static_cast<Eigen::Index>(nf), 3);
  const char* p = payload.data() + 8;
  for (std::uint64_t i = 0; i < nv; ++i) {
    for (int c = 0; c < 3; ++c) {
      float v = 0;
      std::memcpy(&v, p, 4);
      p += 4;
      RB_CHECK(std::isfinite(v), "mesh payload: vertex ", i, " has a coordinate that is not finite");
      m.V(static_cast<Eigen::Index>(i), c) = v;
    }
  }
  for (std::uint64_t f = 0; f < nf; ++f) {
    for (int c = 0; c < 3; ++c) {
      std::uint32_t v = 0;
      std::memcpy(&v, p, 4);
      p += 4;
      RB_CHECK(v < nv, "mesh payload: face ", f, " names vertex ", v, " of ", nv);
      m.F(static_cast<Eigen::Index>(f), c) = static_cast<int>(v);
    }
  }
  return m;
}

void WireMeshOptions::Check() const {
  RB_CHECK(max_faces >= 100, "wire mesh: max_faces must be >= 100, got ", max_faces);
}

Mesh WireMesh(const Mesh& mesh, const WireMeshOptions& options) {
  options.Check();
  if (mesh.num_faces() <= options.max_faces) {
    Mesh out;
    out.V = mesh.V;
    out.F = mesh.F;
    return out;
  }
  double area = 0.0;
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)).transpose();
    const Eigen::Vector3d b = mesh.V.row(mesh.F(f, 1)).transpose();
    const Eigen::Vector3d c = mesh.V.row(mesh.F(f, 2)).transpose();
    area += 0.5 * (b - a).cross(c - a).norm();
  }
  // A surface cut into square cells of side h has about area / h² cells, each carrying about two triangles.
  double cell = std::sqrt(2.0 * area / static_cast<double>(options.max_faces));
  if (!(cell > 0.0) || !std::isfinite(cell)) cell = 1e-6;
  const Eigen::RowVector3d lo = mesh.V.colwise().minCoeff();
  std::unordered_map<std::uint64_t, int> cell_vertex;
  std::vector<int> remap(static_cast<size_t>(mesh.num_vertices()));
  std::vector<Eigen::RowVector3d> sum;
  std::vector<int> count;
  for (int i = 0; i < mesh.num_vertices(); ++i) {
    const Eigen::RowVector3d q = (mesh.V.row(i) - lo) / cell;
    const auto key_of = [](double v) { return static_cast<std::uint64_t>(std::max(0.0, std::floor(v))) & 0x1fffffu; };
    const std::uint64_t key = key_of(q.x()) | (key_of(q.y()) << 21) | (key_of(q.z()) << 42);
    auto [it, inserted] = cell_vertex.try_emplace(key, static_cast<int>(sum.size()));
    if (inserted) {
      sum.push_back(Eigen::RowVector3d::Zero());
      count.push_back(0);
    }
    sum[static_cast<size_t>(it->second)] += mesh.V.row(i);
    ++count[static_cast<size_t>(it->second)];
    remap[static_cast<size_t>(i)] = it->second;
  }
  Mesh out;
  out.V.resize(static_cast<Eigen::Index>(sum.size()), 3);
  for (size_t k = 0; k < sum.size(); ++k) out.V.row(static_cast<Eigen::Index>(k)) = sum[k] / count[k];
  std::vector<int> faces;
  faces.reserve(static_cast<size_t>(mesh.num_faces()));
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const int a = remap[static_cast<size_t>(mesh.F(f, 0))];
    const int b = remap[static_cast<size_t>(mesh.F(f, 1))];
    const int c = remap[static_cast<size_t>(mesh.F(f, 2))];
    if (a == b || b == c || a == c) continue;
    faces.insert(faces.end(), {a, b, c});
  }
  out.F.resize(static_cast<Eigen::Index>(faces.size() / 3), 3);
  for (size_t f = 0; f < faces.size() / 3; ++f) {
    for (int c = 0; c < 3; ++c) out.F(static_cast<Eigen::Index>(f), c) = faces[3 * f + static_cast<size_t>(c)];
  }
  return out;
}

UiAddress ParseUiAddress(const std::string& text) {
  UiAddress a;
  std::string port = text;
  const size_t colon = text.rfind(':');
  if (colon != std::string::npos) {
    a.address = text.substr(0, colon);
    port = text.substr(colon + 1);
    RB_CHECK(!a.address.empty(), "--ui ", text, ": empty address before ':'");
    // An IPv6 address in brackets, as in a URL ("[::1]:8080"; it was refused as not numeric).
    if (a.address.size() > 2 && a.address.front() == '[' && a.address.back() == ']') {
      a.address = a.address.substr(1, a.address.size() - 2);
    }
  }
  RB_CHECK(!port.empty() && port.size() <= 5 && std::all_of(port.begin(), port.end(), [](char c) {
             return c >= '0' && c <= '9';
           }),
           "--ui ", text, ": expected [ADDR:]PORT with PORT a number 0-65535");
  a.port = std::stoi(port);
  RB_CHECK(a.port <= 65535, "--ui ", text, ": port ", a.port, " is above 65535");
  return a;
}

bool IsLoopbackAddress(const std::string& address) { return address == "::1" || address.starts_with("127."); }

bool ConstantTimeEqual(std::string_view a, std::string_view b) {
  // Compares over the longer length so that the time does not depend on where the strings differ.
  const size_t n = std::max(a.size(), b.size());
  unsigned char diff = a.size() == b.size() ? 0 : 1;
  for (size_t i = 0; i < n; ++i) {
    const unsigned char x = i < a.size() ? static_cast<unsigned char>(a[i]) : 0;
    const unsigned char y = i < b.size() ? static_cast<unsigned char>(b[i]) : 0;
    diff |= static_cast<unsigned char>(x ^ y);
  }
  return diff == 0;
}

std::string MakeConsoleToken() {
  std::random_device device;
  static const char kHex[] = "0123456789abcdef";
  std::string token;
  for (int i = 0; i < 8; ++i) {
    const std::uint32_t v = device();
    for (int k = 0; k < 4; ++k) token.push_back(kHex[(v >> (4 * k)) & 0xfu]);
  }
  return token;
}

bool IsValidRecordingName(std::string_view name) {
  if (name.empty() || name.size() > 64 || name.front() == '.') return false;
  return std::all_of(name.begin(), name.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' || c == '_' ||
           c == '-';
  });
}

}  // namespace rangebayes

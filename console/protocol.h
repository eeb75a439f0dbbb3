// The wire format of the operator's console (web/console.js reads it) and the small checks its server makes:
// binary WebSocket messages (images, meshes), the mesh reduction for the wire, the [ADDR:]PORT flag, tokens,
// names of recordings created from the page.
//
// A binary message is: 1 byte type (1 image, 2 mesh), 3 bytes zero, a little-endian uint32 header length n,
// n bytes of JSON header (UTF-8), zero padding to a multiple of 4 bytes, then the payload.
// Image payload: the JPEG or PNG file. Mesh payload: uint32 #V, uint32 #F, #V×3 float32 positions (metres,
// camera frame), #F×3 uint32 vertex indices.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "core/mesh.h"

namespace rangebayes {

enum class ConsoleMessageType : std::uint8_t { kImage = 1, kMesh = 2 };

// Builds one binary message from its JSON header and payload.
std::string EncodeConsoleMessage(ConsoleMessageType type, const nlohmann::json& header, std::string_view payload);

// The parts of a binary message; throws Error when `message` is not one (truncated, bad lengths, bad JSON).
struct ConsoleMessage {
  ConsoleMessageType type = ConsoleMessageType::kImage;
  nlohmann::json header;
  std::string_view payload;  // points into the decoded message
};
ConsoleMessage DecodeConsoleMessage(std::string_view message);

// The mesh payload (counts, float32 positions, uint32 faces) and its inverse (throws Error on a bad payload:
// wrong length, a face naming a missing vertex, a position that is not finite).
std::string EncodeMeshPayload(const Mesh& mesh);
Mesh DecodeMeshPayload(std::string_view payload);

struct WireMeshOptions {
  int max_faces = 20000;  // ≥ 100: meshes with more faces are vertex-clustered to about this many
  void Check() const;
};

// A mesh small enough for the wire: the input when it has at most options.max_faces faces, else a vertex
// clustering (one vertex per occupied grid cell at the mean of its vertices; faces that collapse are dropped)
// with the cell size chosen from the surface area so that about max_faces faces remain.
Mesh WireMesh(const Mesh& mesh, const WireMeshOptions& options = {});

// "--ui [ADDR:]PORT": address (default 127.0.0.1; an IPv6 one may be in brackets, "[::1]:8080") and port 0–65535
// (0: any free port). Throws Error.
struct UiAddress {
  std::string address = "127.0.0.1";
  int port = 0;
};
UiAddress ParseUiAddress(const std::string& text);

// Whether a numeric address (as UiAddress holds it) is a loopback one: 127.0.0.0/8 or ::1.
bool IsLoopbackAddress(const std::string& address);

// Equal strings in a time that depends only on their lengths (for tokens).
bool ConstantTimeEqual(std::string_view a, std::string_view b);

// 32 hexadecimal digits from the system's random device.
std::string MakeConsoleToken();

// A recording folder name a page may create: 1–64 characters of [A-Za-z0-9._-], not starting with '.'.
bool IsValidRecordingName(std::string_view name);

}  // namespace rangebayes

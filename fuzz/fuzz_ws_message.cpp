// libFuzzer entry for the console's WebSocket messages: what a client may send (ParseClientMessage:
// subscriptions, credit flow, acknowledgements) and the binary wire format the server sends
// (DecodeConsoleMessage, DecodeMeshPayload).
// Any input is accepted or rejected (nullopt, or rangebayes::Error for the binary decoders); what is
// accepted is within the limits, and a decoded mesh has finite positions and faces inside its vertices.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "console/protocol.h"
#include "console/server.h"
#include "core/error.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rangebayes;
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  if (const auto message = ParseClientMessage(bytes)) {
    fuzz::Require(message->subscribe.size() <= 8 && message->acks.size() <= 8, "at most 8 groups and acks");
    for (const auto& [group, value] : message->subscribe) {
      fuzz::Require(group.size() <= 32 && value.size() <= 32, "short names");
    }
    for (const std::string& topic : message->acks) fuzz::Require(topic.size() <= 32, "short topics");
  }
  try {
    const ConsoleMessage message = DecodeConsoleMessage(bytes);
    fuzz::Require(message.header.is_object(), "header object");
    fuzz::Require(message.payload.data() >= bytes.data() &&
                      message.payload.data() + message.payload.size() <= bytes.data() + bytes.size(),
                  "payload inside the message");
    if (message.type == ConsoleMessageType::kMesh) {
      const Mesh mesh = DecodeMeshPayload(message.payload);
      fuzz::RequireFinite(mesh.V, "mesh positions");
      if (mesh.num_faces() > 0) {
        fuzz::Require(mesh.F.minCoeff() >= 0 && mesh.F.maxCoeff() < mesh.num_vertices(), "faces index vertices");
      }
    }
  } catch (const Error&) {
  }
  return 0;
}

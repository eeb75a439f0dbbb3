// libFuzzer entry for the console server's HTTP request parser (ParseHttpRequest, what a connection's bytes
// become before the console's handler sees them; no socket): any input is accepted as a request, refused with
// an HTTP status, or incomplete; an accepted request is within the server's limits.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "console/server.h"
#include "core/error.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rangebayes;
  const ConsoleServerOptions options;
  const HttpParseResult r = ParseHttpRequest(std::string_view(reinterpret_cast<const char*>(data), size), options);
  if (!r.complete || r.refuse_status != 0) {
    fuzz::Require(r.refuse_status == 0 || (r.refuse_status >= 400 && r.refuse_status < 600), "refusal status");
    return 0;
  }
  fuzz::Require(!r.request.method.empty(), "a method");
  fuzz::Require(r.request.target.size() <= static_cast<size_t>(options.max_target_chars), "target within limit");
  fuzz::Require(r.request.body.size() <= static_cast<size_t>(options.max_body_bytes), "body within limit");
  fuzz::Require(r.consumed <= size, "consumed within the input");
  for (const auto& [name, value] : r.request.headers) {
    for (const char c : name) fuzz::Require(!(c >= 'A' && c <= 'Z'), "lower-case header names");
  }
  return 0;
}

// libFuzzer entry for batch task status files (ParseBatchTaskStatus) and batch.json (ReadBatchRecord): any
// input parses or throws rangebayes::Error; a status parsed has a known state and a finite duration and
// survives BatchTaskStatusJson → ParseBatchTaskStatus unchanged.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "batch/task.h"
#include "core/error.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rangebayes;
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    const BatchTaskStatus s = ParseBatchTaskStatus(text, "fuzz.json");
    fuzz::Require(s.state == "running" || s.state == "succeeded" || s.state == "partial" || s.state == "failed",
                  "known state");
    fuzz::RequireFinite(s.duration_s, "duration_s");
    const BatchTaskStatus back = ParseBatchTaskStatus(BatchTaskStatusJson(s), "round trip");
    fuzz::Require(back.index == s.index && back.state == s.state && back.exit_code == s.exit_code &&
                      back.attempt == s.attempt && back.run == s.run && back.job_id == s.job_id &&
                      back.host == s.host && back.pid == s.pid && back.error_line == s.error_line &&
                      back.command == s.command && back.duration_s == s.duration_s,
                  "status round trip");
  } catch (const Error&) {
  }
  try {
    fuzz::WriteScratch("batch/batch.json", text);
    const BatchRecord record = ReadBatchRecord(BatchLayout(fuzz::ScratchDir() + "/batch"));
    fuzz::Require(record.num_tasks >= 0, "num_tasks >= 0");
  } catch (const Error&) {
  }
  return 0;
}

#include "capture/recorder.h"

#include <chrono>

#include "core/error.h"

namespace rangebayes {

void RecorderOptions::Check() const {
  RB_CHECK(max_frames >= 0, "max_frames must be >= 0, got ", max_frames);
  RB_CHECK(max_duration_s >= 0.0, "max_duration_s must be >= 0, got ", max_duration_s);
  RB_CHECK(max_consecutive_timeouts >= 1, "max_consecutive_timeouts must be >= 1, got ", max_consecutive_timeouts);
}

const char* ToString(RecorderStop stop) {
  switch (stop) {
    case RecorderStop::kEndOfStream: return "end of stream";
    case RecorderStop::kStopRequested: return "stop requested";
    case RecorderStop::kMaxFrames: return "frame limit reached";
    case RecorderStop::kMaxDuration: return "time limit reached";
    case RecorderStop::kStalled: return "source stalled";
    case RecorderStop::kSourceError: return "source error";
    case RecorderStop::kWriteFailed:
      return "write failed";
  }
  return "unknown";
}

RecorderSummary Record(FrameSource& source, RecordingWriter& writer, const RecorderOptions& options,
                       const ProgressCallback& progress) {
  options.Check();
  RecorderSummary summary;
  const auto start = std::chrono::steady_clock::now();
  auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); };
  int consecutive_timeouts = 0;
  std::int64_t next_index = 0;
  while (true) {
    if (options.stop != nullptr && options.stop->load(std::memory_order_relaxed)) {
      summary.stop = RecorderStop::kStopRequested;
      break;
    }
    if (options.max_frames > 0 && summary.frames_written >= options.max_frames) {
      summary.stop = RecorderStop::kMaxFrames;
      break;
    }
    if (options.max_duration_s > 0 && elapsed() >= options.max_duration_s) {
      summary.stop = RecorderStop::kMaxDuration;
      break;
    }
    FrameResult r;
    try {
      r = source.Next();
    } catch (const std::exception& e) {
      summary.stop = RecorderStop::kSourceError;
      summary.error = e.what();
      break;
    }
    if (r.status == FrameStatus::kEndOfStream) {
      summary.stop = RecorderStop::kEndOfStream;
      break;
    }
    if (r.status == FrameStatus::kTimeout) {
      ++summary.timeouts;
      if (++consecutive_timeouts >= options.max_consecutive_timeouts) {
        summary.stop = RecorderStop::kStalled;
        summary.error = StrCat(source.Describe(), ": no frame after ", consecutive_timeouts, " timeouts",
                               r.reason.empty() ? "" : " (" + r.reason + ")");
        break;
      }
      continue;
    }
    consecutive_timeouts = 0;
    if (r.status == FrameStatus::kSkipped) {
      ++summary.frames_skipped;
      continue;
    }
    // Camera sources number from 0; a recording being re-recorded keeps its indices when they increase.
    if (r.frame.index < next_index) r.frame.index = next_index;
    try {
      writer.Write(r.frame);
    } catch (const std::exception& e) {
      summary.stop = RecorderStop::kWriteFailed;
      summary.error = e.what();
      break;
    }
    next_index = r.frame.index + 1;
    ++summary.frames_written;
    if (progress) {
      const double fraction =
          options.max_frames > 0 ? static_cast<double>(summary.frames_written) / options.max_frames : 0.0;
      progress(fraction, "recording");
    }
  }
  summary.source = source.stats();
  summary.elapsed_s = elapsed();
  RecordingMeta extra = {{"stopped", ToString(summary.stop)}};
  if (!summary.error.empty()) extra["error"] = summary.error;
  try {
    writer.Finish(extra);
  } catch (const std::exception& e) {
    if (summary.error.empty()) summary.error = e.what();
  }
  return summary;
}

std::string RecorderSummary::BriefReport() const {
  return StrCat(frames_written, " frames in ", elapsed_s, " s (", ToString(stop), "); dropped by the drivers: left ",
                source.dropped_left, ", right ", source.dropped_right, "; unpaired: left ", source.unpaired_left,
                ", right ", source.unpaired_right, "; timeouts ", timeouts);
}

}  // namespace rangebayes

// Recorder: pulls frames from a FrameSource and writes them into a recording until the source ends, a stop
// is requested (Ctrl-C), a limit is reached, or the device is lost. The index is finished in every case.
#pragma once

#include <atomic>
#include <cstdint>
#include <string>

#include "capture/frame_source.h"
#include "capture/recording.h"
#include "core/progress.h"

namespace rangebayes {

struct RecorderOptions {
  std::int64_t max_frames = 0;           // ≥ 0: stop after this many frames (0: no limit)
  double max_duration_s = 0.0;           // ≥ 0: stop after this much wall time (0: no limit)
  int max_consecutive_timeouts = 20;     // ≥ 1: a stalled source ends the recording after this many
  const std::atomic<bool>* stop = nullptr;  // polled between frames (e.g. &StopFlag()); null: never
  void Check() const;
};

// kWriteFailed: the writer failed (a full disk): the frame in flight is lost, the frames before it are kept.
enum class RecorderStop {
  kEndOfStream,
  kStopRequested,
  kMaxFrames,
  kMaxDuration,
  kStalled,
  kSourceError,
  kWriteFailed
};

struct RecorderSummary {
  std::int64_t frames_written = 0;
  std::int64_t frames_skipped = 0;
  std::int64_t timeouts = 0;
  RecorderStop stop = RecorderStop::kEndOfStream;
  std::string error;                 // kSourceError / kStalled / a write failure: one line
  FrameSourceStats source;           // the source's counters at the end
  double elapsed_s = 0.0;

  // One line: frames, time, why it stopped, the drivers' drops, unpaired frames and timeouts.
  std::string BriefReport() const;
};

const char* ToString(RecorderStop stop);

// Never throws for a source failure (that ends the recording with stop = kSourceError and `error` set,
// the frames so far kept and indexed). A write failure (disk full) also finishes what was written and is
// reported in `error`. Progress: fraction of max_frames when given, else 0.
RecorderSummary Record(FrameSource& source, RecordingWriter& writer, const RecorderOptions& options = {},
                       const ProgressCallback& progress = {});

}  // namespace rangebayes

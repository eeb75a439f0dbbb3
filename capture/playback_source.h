// A recording played back as a FrameSource: at recorded speed, as fast as possible, or one frame at a time.
#pragma once

#include <atomic>
#include <chrono>
#include <functional>

#include "capture/frame_source.h"
#include "capture/recording.h"

namespace rangebayes {

enum class PlaybackSpeed {
  kFastest,   // no waiting
  kRecorded,  // frames released at their recorded time gaps (scaled by speed_factor)
  kStep,      // each frame waits for step_gate() (e.g. the user pressing Enter)
};

struct PlaybackOptions {
  PlaybackSpeed speed = PlaybackSpeed::kFastest;
  double speed_factor = 1.0;         // (0, 1000]: kRecorded plays this many times faster than recorded
  int first_position = 0;            // ≥ 0: first entry of frames.csv to play (position, not index)
  int count = -1;                    // -1: to the end; otherwise at most this many entries
  bool loop = false;                 // start again after the last entry (live-path benchmarks)
  int repeats = 1;                   // 1–1e6: play the selection this many times (ignored with loop)
  std::function<bool()> step_gate;   // kStep: called before each frame; false ends the stream
  // kRecorded: the wait for a frame's recorded time polls this (every 20 ms) and ends the stream when it is set
  // (e.g. &StopFlag()), so that Ctrl-C or SIGTERM ends a long gap between two frames; null: never.
  const std::atomic<bool>* stop = nullptr;
  // kRecorded: the longest wait between two frames (seconds of wall time); a longer gap between their recorded
  // times (a pause, a damaged timestamp) is played as this and counted in FrameSourceStats::gaps_shortened.
  // A timestamp 4e18 ns ahead made replay sleep without end. > 0.
  double max_gap_s = 10.0;
  void Check() const;
};

// Missing or corrupt images are returned as kSkipped with the frame index and file in `reason`; the
// stream goes on with the next entry. Repeats and loops number the frames of each pass after the last of the
// pass before; Next throws Error naming the recording when a pass would number one past kMaxRecordingIndex.
class PlaybackSource : public FrameSource {
 public:
  PlaybackSource(Recording recording, const PlaybackOptions& options = {});

  FrameResult Next() override;
  std::string Describe() const override;
  FrameSourceStats stats() const override { return stats_; }
  RecordingMeta Meta() const override;
  std::optional<std::int64_t> frames_total() const override;
  bool realtime() const override { return options_.speed == PlaybackSpeed::kRecorded; }

  // Random access by position in frames.csv (0 ≤ position < num_frames) or by the recorded frame index.
  // Throw Error naming the index when the frame cannot be loaded.
  StereoFrame FrameAt(int position) const;
  StereoFrame FrameWithIndex(std::int64_t index) const;
  void Seek(int position);
  int position() const { return position_; }
  const Recording& recording() const { return recording_; }

 private:
  Recording recording_;
  PlaybackOptions options_;
  FrameSourceStats stats_;
  int position_ = 0;
  int end_position_ = 0;
  bool clock_started_ = false;
  std::chrono::steady_clock::time_point wall_start_;
  std::int64_t recorded_start_ns_ = 0;
  double gaps_cut_s_ = 0.0;     // recorded time (scaled) left out by gaps cut to max_gap_s
  double last_offset_s_ = 0.0;  // when the last frame was due, seconds after the first
  std::int64_t loop_index_offset_ = 0;
  int plays_done_ = 0;  // completed passes over the selection
};

}  // namespace rangebayes

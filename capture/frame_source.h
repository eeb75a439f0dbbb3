// The interface every producer of stereo frames implements: cameras (V4L2, libcamera) and recordings.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "capture/recording.h"
#include "capture/stereo_frame.h"

namespace rangebayes {

enum class FrameStatus {
  kFrame,        // `frame` holds a complete pair
  kEndOfStream,  // no more frames (end of a recording, a step gate said stop)
  kTimeout,      // no pair within the source's timeout; calling Next again is fine
  kSkipped,      // a frame could not be delivered (missing/corrupt image, undecodable buffer); `reason` says why
};

struct FrameResult {
  FrameStatus status = FrameStatus::kEndOfStream;
  StereoFrame frame;
  std::string reason;  // for kSkipped and kTimeout: one line naming the frame or device
};

// Counters a source keeps while it runs.
struct FrameSourceStats {
  std::int64_t frames_delivered = 0;
  std::int64_t frames_skipped = 0;
  std::int64_t timeouts = 0;
  std::int64_t dropped_left = 0;    // gaps in the driver's sequence numbers (frames the driver lost)
  std::int64_t dropped_right = 0;
  std::int64_t unpaired_left = 0;   // images discarded because no partner arrived within the tolerance
  std::int64_t unpaired_right = 0;
  std::int64_t gaps_shortened = 0;  // playback at recorded speed: waits cut to PlaybackOptions::max_gap_s
};

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  // Blocks until a pair is ready, the source's timeout passes, or the stream ends. Throws Error when the
  // device is lost (unplugged: ENODEV) or fails for good; frames already delivered stay valid.
  virtual FrameResult Next() = 0;
  // One line describing the source ("recording recordings/synth_plane (16 frames)").
  virtual std::string Describe() const = 0;
  virtual FrameSourceStats stats() const = 0;
  // Key/values for a recording's meta.yaml (device names, negotiated formats).
  virtual RecordingMeta Meta() const { return {{"source", Describe()}}; }
  // The number of frames still to come when known in advance (recordings), for progress and time left.
  virtual std::optional<std::int64_t> frames_total() const { return std::nullopt; }
  // True when frames arrive at their own pace whether or not anyone takes them (cameras, recordings played
  // at the recorded speed); false when the next frame exists only when asked for (recordings played as fast
  // as possible or one step at a time). A live pipeline drops frames only from a real-time source.
  virtual bool realtime() const { return true; }
};

}  // namespace rangebayes

// A FrameSource that records every frame of another source as it passes (rangebayes live --record).
#pragma once

#include <string>

#include "capture/frame_source.h"
#include "capture/recording.h"

namespace rangebayes {

// Next() returns the inner source's result after writing its frame (status kFrame) to `writer`, so that
// recording happens in the capture thread, before any frame can be dropped downstream. Everything else is
// the inner source's. Both must outlive the tee; writer may be null (a plain pass-through). A write failure
// throws Error from Next().
class TeeSource : public FrameSource {
 public:
  TeeSource(FrameSource& inner, RecordingWriter* writer) : inner_(inner), writer_(writer) {}
  FrameResult Next() override;
  std::string Describe() const override { return inner_.Describe(); }
  FrameSourceStats stats() const override { return inner_.stats(); }
  RecordingMeta Meta() const override { return inner_.Meta(); }
  std::optional<std::int64_t> frames_total() const override { return inner_.frames_total(); }
  bool realtime() const override { return inner_.realtime(); }

 private:
  FrameSource& inner_;
  RecordingWriter* writer_;
};

}  // namespace rangebayes

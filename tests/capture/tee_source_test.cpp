#include "capture/tee_source.h"

#include <gtest/gtest.h>

#include "capture/recording.h"
#include "test_util.h"

namespace rangebayes {
namespace {

// Every frame that passes is written, timeouts and skips are passed on unwritten, and the frames come out
// unchanged in order.
TEST(TeeSource, RecordsEveryFrameThatPasses) {
  const TempDir dir("tee");
  FakeFrameSource source(32, 16, 6);
  source.hook = [](std::int64_t i) { return i == 2 ? FrameStatus::kTimeout : FrameStatus::kFrame; };
  RecordingWriter writer(dir.path() + "/rec", std::nullopt, source.Meta());
  TeeSource tee(source, &writer);
  EXPECT_EQ(tee.Describe(), source.Describe());
  std::vector<std::int64_t> passed;
  for (FrameResult r = tee.Next(); r.status != FrameStatus::kEndOfStream; r = tee.Next()) {
    if (r.status == FrameStatus::kFrame) passed.push_back(r.frame.index);
  }
  writer.Finish();
  EXPECT_EQ(passed, (std::vector<std::int64_t>{0, 1, 3, 4, 5}));
  const Recording rec = OpenRecording(dir.path() + "/rec");
  ASSERT_EQ(rec.num_frames(), 5);
  EXPECT_EQ(LoadRecordingFrame(rec, 2).index, 3);
  EXPECT_EQ(tee.stats().timeouts, 1);
}

TEST(TeeSource, WithoutWriterPassesThrough) {
  FakeFrameSource source(32, 16, 2);
  TeeSource tee(source, nullptr);
  EXPECT_EQ(tee.Next().status, FrameStatus::kFrame);
  EXPECT_EQ(tee.Next().status, FrameStatus::kFrame);
  EXPECT_EQ(tee.Next().status, FrameStatus::kEndOfStream);
}

}  // namespace
}  // namespace rangebayes

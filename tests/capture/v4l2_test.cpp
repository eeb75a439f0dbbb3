// V4L2 negotiation and streaming against a scripted fake device; pairing; device listing; libcamera
// without cameras; real hardware when present (skipped otherwise).
#include <fcntl.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "capture/device_list.h"
#include "capture/libcamera_source.h"
#include "capture/recorder.h"
#include "capture/v4l2_source.h"
#include "core/error.h"
#include "tests/capture/fake_v4l2.h"
#include "tests/capture/test_util.h"

namespace rangebayes {
namespace {

// Frames every 33 ms from t0, sequences from 0, optional skipped sequence numbers.
std::deque<FakeEvent> Stream(int n, std::int64_t t0_ns, std::uint8_t value0, std::vector<int> lost = {}) {
  std::deque<FakeEvent> s;
  std::uint32_t seq = 0;
  for (int i = 0; i < n; ++i) {
    while (std::find(lost.begin(), lost.end(), static_cast<int>(seq)) != lost.end()) ++seq;
    FakeEvent e;
    e.timestamp_ns = t0_ns + static_cast<std::int64_t>(seq) * 33'333'333;
    e.sequence = seq++;
    e.value = static_cast<std::uint8_t>(value0 + i);
    s.push_back(e);
  }
  return s;
}

TEST(V4l2Camera, NegotiatesClosestSizeAndPreferredFormat) {
  auto fake = std::make_shared<FakeV4l2>();
  fake->devices["/dev/video0"].formats = {V4L2_PIX_FMT_MJPEG, V4L2_PIX_FMT_YUYV};
  fake->devices["/dev/video0"].fps = 25.0;
  V4l2CameraOptions o;
  o.width = 600;
  o.height = 460;
  V4l2Camera cam(fake, "/dev/video0", o);
  EXPECT_EQ(cam.format().fourcc, FourccYuyv());  // GREY not offered; YUYV preferred over MJPEG
  EXPECT_EQ(cam.format().width, 640);
  EXPECT_EQ(cam.format().height, 480);
  EXPECT_DOUBLE_EQ(cam.format().fps, 25.0);
  EXPECT_FALSE(cam.format().exact);
  EXPECT_NE(cam.format().Describe().find("YUYV 640x480 25.00 fps (closest offered)"), std::string::npos)
      << cam.format().Describe();

  V4l2CameraOptions exact;
  exact.width = 320;
  exact.height = 240;
  exact.fps = 25.0;
  exact.formats = {FourccMjpeg()};
  V4l2Camera cam2(fake, "/dev/video0", exact);
  EXPECT_EQ(cam2.format().fourcc, FourccMjpeg());
  EXPECT_TRUE(cam2.format().exact);
}

TEST(V4l2Camera, ClearErrorsForUnusableDevices) {
  auto fake = std::make_shared<FakeV4l2>();
  fake->devices["/dev/video1"].formats = {v4l2_fourcc('R', 'G', 'B', '3')};
  fake->devices["/dev/video4"].capture_capable = false;
  EXPECT_NE(ErrorOf([&] { V4l2Camera c(fake, "/dev/video1"); }).find("offers none of GREY, YUYV, MJPEG (offers: RGB3)"),
            std::string::npos);
  EXPECT_NE(ErrorOf([&] { V4l2Camera c(fake, "/dev/video4"); }).find("not a video capture device"), std::string::npos);
  EXPECT_NE(ErrorOf([&] { V4l2Camera c(fake, "/dev/video9"); }).find("/dev/video9: no such device"),
            std::string::npos);
  EXPECT_EQ(fake->open_count, fake->close_count);  // failed opens release their descriptor
}

V4l2StereoOptions TwoCameras() {
  V4l2StereoOptions o;
  o.left_device = "/dev/video0";
  o.right_device = "/dev/video2";
  o.camera.width = 320;
  o.camera.height = 240;
  o.timeout_ms = 50;
  return o;
}

TEST(V4l2Stereo, StreamsPairsWithContentTimestampsAndDrops) {
  auto fake = std::make_shared<FakeV4l2>();
  fake->devices["/dev/video0"].script = Stream(5, 1'000'000'000, 10, {2});  // driver lost sequence 2
  fake->devices["/dev/video2"].script = Stream(5, 1'000'400'000, 100, {2});  // 0.4 ms later
  {
    V4l2StereoSource source(fake, TwoCameras());
    EXPECT_EQ(fake->streaming_devices(), 2);
    for (int i = 0; i < 5; ++i) {
      const FrameResult r = source.Next();
      ASSERT_EQ(r.status, FrameStatus::kFrame) << r.reason;
      EXPECT_EQ(r.frame.index, i);
      EXPECT_EQ(r.frame.left.type(), CV_8UC1);
      EXPECT_EQ(r.frame.left.cols, 320);
      EXPECT_EQ(cv::norm(r.frame.left, FakeV4l2::Expected(320, 240, static_cast<std::uint8_t>(10 + i)), cv::NORM_INF), 0);
      EXPECT_EQ(cv::norm(r.frame.right, FakeV4l2::Expected(320, 240, static_cast<std::uint8_t>(100 + i)), cv::NORM_INF),
                0);
      EXPECT_EQ(r.frame.timestamp_right_ns - r.frame.timestamp_left_ns, 400'000);
    }
    EXPECT_EQ(source.Next().status, FrameStatus::kTimeout);  // script ran out: nothing ready
    const FrameSourceStats s = source.stats();
    EXPECT_EQ(s.frames_delivered, 5);
    EXPECT_EQ(s.dropped_left, 1);
    EXPECT_EQ(s.dropped_right, 1);
    EXPECT_EQ(s.timeouts, 1);
  }
  EXPECT_EQ(fake->streaming_devices(), 0);
  EXPECT_EQ(fake->mapped_now, 0);
  EXPECT_EQ(fake->open_count, fake->close_count);
}

TEST(V4l2Stereo, UnmatchedImagesAreDiscardedAndCounted) {
  auto fake = std::make_shared<FakeV4l2>();
  // Right starts one frame earlier: its first image has no left partner within 10 ms.
  fake->devices["/dev/video0"].script = Stream(3, 1'033'333'333, 0);
  fake->devices["/dev/video2"].script = Stream(4, 1'000'000'000, 0);
  V4l2StereoSource source(fake, TwoCameras());
  int pairs = 0;
  for (FrameResult r = source.Next(); r.status == FrameStatus::kFrame; r = source.Next()) {
    EXPECT_LE(std::llabs(r.frame.timestamp_left_ns - r.frame.timestamp_right_ns), 10'000'000);
    ++pairs;
  }
  EXPECT_EQ(pairs, 3);
  EXPECT_EQ(source.stats().unpaired_right, 1);
}

TEST(V4l2Stereo, StallingDeviceTimesOutAndRecorderEndsCleanly) {
  auto fake = std::make_shared<FakeV4l2>();
  fake->devices["/dev/video0"].script = Stream(2, 1'000'000'000, 0);
  fake->devices["/dev/video2"].script = Stream(2, 1'000'000'000, 0);
  for (int i = 0; i < 10; ++i) fake->devices["/dev/video2"].script.push_back({FakeEvent::kStall, 0, 0, 0});
  V4l2StereoSource source(fake, TwoCameras());
  const TempDir dir("stall4l2");
  RecordingWriter writer(dir.path() + "/rec", std::nullopt, source.Meta());
  RecorderOptions options;
  options.max_consecutive_timeouts = 3;
  const RecorderSummary s = Record(source, writer, options);
  EXPECT_EQ(s.stop, RecorderStop::kStalled);
  EXPECT_EQ(s.frames_written, 2);
  EXPECT_NE(s.error.find("timeouts"), std::string::npos) << s.error;
  const Recording rec = OpenRecording(dir.path() + "/rec");
  EXPECT_EQ(rec.num_frames(), 2);
  EXPECT_NE(rec.meta.at("left_format").find("YUYV 320x240"), std::string::npos);
}

TEST(V4l2Stereo, UnpluggedDeviceIsAClearErrorAndTheRecordingIsKept) {
  auto fake = std::make_shared<FakeV4l2>();
  fake->devices["/dev/video0"].script = Stream(6, 1'000'000'000, 0);
  fake->devices["/dev/video2"].script = Stream(3, 1'000'000'000, 0);
  fake->devices["/dev/video2"].script.push_back({FakeEvent::kUnplug, 0, 0, 0});
  V4l2StereoSource source(fake, TwoCameras());
  const TempDir dir("unplug");
  RecordingWriter writer(dir.path() + "/rec", std::nullopt, source.Meta());
  const RecorderSummary s = Record(source, writer);
  EXPECT_EQ(s.stop, RecorderStop::kSourceError);
  EXPECT_NE(s.error.find("/dev/video2: device disappeared"), std::string::npos) << s.error;
  EXPECT_EQ(s.frames_written, 3);
  const Recording rec = OpenRecording(dir.path() + "/rec");
  EXPECT_EQ(rec.num_frames(), 3);
  EXPECT_EQ(rec.meta.at("complete"), "true");
}

TEST(V4l2Stereo, MjpegDecodesAndCorruptBuffersAreSkipped) {
  auto fake = std::make_shared<FakeV4l2>();
  for (const char* dev : {"/dev/video0", "/dev/video2"}) {
    fake->devices[dev].formats = {V4L2_PIX_FMT_MJPEG};
    fake->devices[dev].script = Stream(3, 1'000'000'000, 50);
  }
  fake->devices["/dev/video0"].script[1].kind = FakeEvent::kCorrupt;
  // Cut short: libjpeg decoded it with a warning on stderr, the missing half grey, and it was delivered.
  fake->devices["/dev/video2"].script[2].kind = FakeEvent::kTruncated;
  V4l2StereoSource source(fake, TwoCameras());
  std::vector<std::int64_t> delivered;
  for (FrameResult r = source.Next(); r.status == FrameStatus::kFrame; r = source.Next()) {
    // JPEG at quality 100 of a smooth ramp: a few grey levels of error at most.
    EXPECT_LE(cv::norm(r.frame.left, FakeV4l2::Expected(320, 240, static_cast<std::uint8_t>(50 + 2 * r.frame.index)),
                       cv::NORM_INF),
              4.0);
    delivered.push_back(r.frame.timestamp_left_ns);
  }
  EXPECT_EQ(delivered.size(), 1u);  // the corrupt left image's right partner found no pair, nor the cut one's left
  EXPECT_EQ(source.stats().frames_skipped, 2);
}

TEST(V4l2Stereo, SideBySideSplitsOneImage) {
  auto fake = std::make_shared<FakeV4l2>();
  fake->devices["/dev/video0"].formats = {V4L2_PIX_FMT_GREY};
  fake->devices["/dev/video0"].sizes = {{640, 240}};
  fake->devices["/dev/video0"].script = Stream(2, 1'000'000'000, 0);
  V4l2StereoOptions o;
  o.side_by_side = true;
  o.left_device = "/dev/video0";
  o.camera.width = 640;
  o.camera.height = 240;
  o.timeout_ms = 10;
  V4l2StereoSource source(fake, o);
  const FrameResult r = source.Next();
  ASSERT_EQ(r.status, FrameStatus::kFrame);
  const cv::Mat whole = FakeV4l2::Expected(640, 240, 0);
  EXPECT_EQ(r.frame.left.cols, 320);
  EXPECT_EQ(cv::norm(r.frame.left, whole.colRange(0, 320), cv::NORM_INF), 0);
  EXPECT_EQ(cv::norm(r.frame.right, whole.colRange(320, 640), cv::NORM_INF), 0);
  EXPECT_EQ(r.frame.timestamp_left_ns, r.frame.timestamp_right_ns);
  EXPECT_NE(source.Describe().find("side-by-side"), std::string::npos);
}

TEST(V4l2Stereo, SameDeviceTwiceIsRejected) {
  auto fake = std::make_shared<FakeV4l2>();
  V4l2StereoOptions o = TwoCameras();
  o.right_device = o.left_device;
  EXPECT_NE(ErrorOf([&] { V4l2StereoSource s(fake, o); }).find("same device"), std::string::npos);
}

TEST(FramePairer, PairsNearestAndCounts) {
  FramePairerOptions o;
  o.tolerance_ns = 5;
  FramePairer p(o);
  auto img = [](std::int64_t t) { return TimedImage{cv::Mat(1, 1, CV_8UC1, cv::Scalar(0)), t, -1}; };
  p.AddLeft(img(100));
  p.AddLeft(img(103));
  p.AddRight(img(104));
  const auto pair = p.Pop();
  ASSERT_TRUE(pair.has_value());
  EXPECT_EQ(pair->first.timestamp_ns, 103);  // nearer than 100
  EXPECT_EQ(p.unpaired_left(), 1);
  EXPECT_FALSE(p.Pop().has_value());
  SequenceGapCounter gaps;
  gaps.Add(5);
  EXPECT_EQ(gaps.Add(9), 3);
  EXPECT_EQ(gaps.dropped(), 3);
}

TEST(DeviceList, ListsFakeDevicesInOrder) {
  const TempDir dir("devlist");
  for (const char* name : {"video10", "video2", "videoX", "null"}) std::ofstream(dir.path() + "/" + name) << "";
  FakeV4l2 fake;
  fake.devices[dir.path() + "/video2"].formats = {V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_MJPEG};
  fake.devices[dir.path() + "/video10"].capture_capable = false;
  const std::vector<V4l2DeviceInfo> list = ListV4l2Devices(fake, dir.path());
  ASSERT_EQ(list.size(), 2u);
  EXPECT_EQ(list[0].path, dir.path() + "/video2");
  EXPECT_TRUE(list[0].can_capture);
  EXPECT_EQ(list[0].formats, (std::vector<std::string>{"YUYV", "MJPG"}));
  EXPECT_FALSE(list[1].can_capture);
  EXPECT_TRUE(ListV4l2Devices(fake, dir.path() + "/none").empty());
}

TEST(Libcamera, ManagerStartsAndStereoNeedsTwoCameras) {
  const LibcameraList list = ListLibcameraCameras();
  if (!list.manager_started) GTEST_SKIP() << "libcamera manager unavailable here: " << list.error;
  if (list.cameras.size() >= 2) GTEST_SKIP() << "real cameras present; the no-camera path is not testable";
  EXPECT_NE(ErrorOf([] { LibcameraStereoSource s(LibcameraStereoOptions{}); }).find("needs two cameras"),
            std::string::npos);
}

// A file that is no video device is refused with one error line: libv4l2 used to print its own
// "libv4l2: error getting capabilities" before it.
TEST(V4l2Camera, NonDeviceIsOneErrorLine) {
  auto sys = RealV4l2SysCalls();
  testing::internal::CaptureStderr();
  const std::string error = ErrorOf([&] { V4l2Camera cam(sys, "/dev/null"); });
  const std::string printed = testing::internal::GetCapturedStderr();
  EXPECT_NE(error.find("/dev/null: not a video capture device"), std::string::npos) << error;
  EXPECT_EQ(printed, "");
}

TEST(V4l2Hardware, RealDeviceNegotiates) {
  if (!std::filesystem::exists("/dev/video0")) GTEST_SKIP() << "no /dev/video0 on this machine";
  auto sys = RealV4l2SysCalls();
  try {
    V4l2Camera cam(sys, "/dev/video0");
    EXPECT_GT(cam.format().width, 0);
  } catch (const Error& e) {
    GTEST_SKIP() << "/dev/video0 is not a usable camera: " << e.what();
  }
}

}  // namespace
}  // namespace rangebayes

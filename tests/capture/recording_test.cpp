// Recording format: writer/reader round trip, index parsing, bad input, and a writer killed mid-stream.
#include "capture/recording.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <vector>

#include "core/error.h"
#include "tests/capture/test_util.h"

namespace rangebayes {
namespace {
namespace fs = std::filesystem;

// The error LoadRecordingFrame gives for frame i, or "no error".
std::string LoadError(const Recording& rec, int i) {
  try {
    LoadRecordingFrame(rec, i);
  } catch (const Error& e) {
    return e.what();
  }
  return "no error";
}

TEST(Recording, RoundTripKeepsImagesTimestampsAndRig) {
  const TempDir dir("roundtrip");
  const std::string folder = dir.path() + "/rec";
  const StereoRig rig = TestRig(64, 48);
  {
    RecordingWriter writer(folder, rig, {{"source", "test"}});
    for (int i = 0; i < 3; ++i) writer.Write(TestFrame(i, 64, 48, CV_8UC1));
    writer.Write(TestFrame(5, 64, 48, CV_8UC1));
    writer.Finish({{"note", "done"}});
    EXPECT_EQ(writer.summary().frames_written, 4);
  }
  RecordingReadSummary summary;
  const Recording rec = OpenRecording(folder, &summary);
  ASSERT_EQ(rec.num_frames(), 4);
  EXPECT_FALSE(summary.truncated_last_line);
  EXPECT_EQ(summary.missing_files, 0);
  ASSERT_TRUE(rec.rig.has_value());
  EXPECT_EQ(rec.rig->width, 64);
  EXPECT_EQ(rec.meta.at("source"), "test");
  EXPECT_EQ(rec.meta.at("complete"), "true");
  EXPECT_EQ(rec.meta.at("frame_count"), "4");
  EXPECT_EQ(rec.meta.at("note"), "done");
  ExpectRecordingHoldsTestFrames(rec, 64, 48, CV_8UC1);
}

TEST(Recording, SixteenBitAndColourAreLossless) {
  const TempDir dir("depth16");
  const std::string folder = dir.path() + "/rec";
  {
    RecordingWriter writer(folder, std::nullopt, {});
    writer.Write(TestFrame(0, 32, 16, CV_16UC1));
    writer.Write(TestFrame(1, 32, 16, CV_8UC3));
  }  // destructor finishes
  const Recording rec = OpenRecording(folder);
  EXPECT_FALSE(rec.rig.has_value());
  EXPECT_EQ(rec.meta.at("complete"), "true");
  const StereoFrame a = LoadRecordingFrame(rec, 0);
  EXPECT_EQ(a.left.type(), CV_16UC1);
  EXPECT_EQ(cv::norm(a.left, TestFrame(0, 32, 16, CV_16UC1).left, cv::NORM_INF), 0.0);
  const StereoFrame b = LoadRecordingFrame(rec, 1);
  EXPECT_EQ(b.left.type(), CV_8UC3);
}

TEST(Recording, RefusesToOverwriteAnExistingRecording) {
  const TempDir dir("overwrite");
  const std::string folder = dir.path() + "/rec";
  { RecordingWriter writer(folder, std::nullopt, {}); }
  EXPECT_THROW(RecordingWriter(folder, std::nullopt, {}), Error);
  RecordingWriterOptions options;
  options.overwrite_flag = "--overwrite";
  try {
    RecordingWriter again(folder, std::nullopt, {}, options);
    ADD_FAILURE() << "a recording was written over";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("already holds a recording (frames.csv); choose another folder, or "
                                         "--overwrite to replace it"),
              std::string::npos)
        << e.what();
  }
  // Replaced: the old recording's frames beyond the new ones and its ground truth do not stay beside it.
  options.overwrite = true;
  {
    RecordingWriter writer(folder, std::nullopt, {}, options);
    for (int i = 0; i < 3; ++i) writer.Write(TestFrame(i, 32, 24, CV_8UC1));
  }
  std::filesystem::create_directories(folder + "/ground_truth");
  std::ofstream(folder + "/ground_truth/depth_left_m.pfm") << "old";
  {
    RecordingWriter writer(folder, std::nullopt, {}, options);
    writer.Write(TestFrame(0, 32, 24, CV_8UC1));
  }
  EXPECT_EQ(OpenRecording(folder).num_frames(), 1);
  size_t left_files = 0;
  for ([[maybe_unused]] const auto& entry : std::filesystem::directory_iterator(folder + "/left")) ++left_files;
  EXPECT_EQ(left_files, 1u);
  EXPECT_FALSE(std::filesystem::exists(folder + "/ground_truth"));
}

TEST(Recording, WriterRejectsMismatchedAndNonIncreasingFrames) {
  const TempDir dir("reject");
  RecordingWriter writer(dir.path() + "/rec", std::nullopt, {});
  StereoFrame f = TestFrame(3, 32, 16, CV_8UC1);
  f.right = cv::Mat(8, 8, CV_8UC1, cv::Scalar(0));
  EXPECT_THROW(writer.Write(f), Error);
  writer.Write(TestFrame(3, 32, 16, CV_8UC1));
  EXPECT_THROW(writer.Write(TestFrame(3, 32, 16, CV_8UC1)), Error);
  StereoFrame floating = TestFrame(4, 32, 16, CV_8UC1);
  floating.left.convertTo(floating.left, CV_32F);
  floating.right.convertTo(floating.right, CV_32F);
  EXPECT_THROW(writer.Write(floating), Error);
}

TEST(RecordingIndex, ParsesAndToleratesTruncatedLastLine) {
  const std::string header = std::string(kRecordingIndexHeader) + "\n";
  RecordingReadSummary s;
  const auto entries = ParseRecordingIndex(header + "0,10,11,left/a.png,right/a.png,-1\n1,20,21,left/b.png,rig", "x", &s);
  ASSERT_EQ(entries.size(), 1u);
  EXPECT_EQ(entries[0].timestamp_right_ns, 11);
  EXPECT_EQ(entries[0].left, "left/a.png");
  EXPECT_TRUE(s.truncated_last_line);
  ASSERT_EQ(s.notices.size(), 1u);
  EXPECT_NE(s.notices[0].find("line 3"), std::string::npos) << s.notices[0];
}

TEST(RecordingIndex, CompleteLastLineWithoutNewlineIsKept) {
  RecordingReadSummary s;
  const auto entries =
      ParseRecordingIndex(std::string(kRecordingIndexHeader) + "\n4,1,2,l.png,r.png,7", "x", &s);
  ASSERT_EQ(entries.size(), 1u);
  EXPECT_EQ(entries[0].pattern_id, 7);
  EXPECT_FALSE(s.truncated_last_line);
}

// An index saved by an editor that puts a UTF-8 byte order mark first: read (the header was refused with
// "expected header 'index,…' got 'index,…'", two strings that printed alike).
TEST(RecordingIndex, AByteOrderMarkBeforeTheHeaderIsSkipped) {
  RecordingReadSummary s;
  const auto entries =
      ParseRecordingIndex("\xEF\xBB\xBF" + std::string(kRecordingIndexHeader) + "\n4,1,2,l.png,r.png,7\n", "x", &s);
  ASSERT_EQ(entries.size(), 1u);
  EXPECT_EQ(entries[0].index, 4);
}

TEST(RecordingIndex, MalformedLinesNameLineAndField) {
  const std::string header = std::string(kRecordingIndexHeader) + "\n";
  auto message = [&](const std::string& body) {
    try {
      ParseRecordingIndex(header + body, "frames.csv");
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message("x,1,2,l,r,0\n").find("line 2 field 'index'"), std::string::npos);
  EXPECT_NE(message("0,1,2,l,r,0\n0,1,2,l,r,0\n").find("line 3 index 0 does not increase"), std::string::npos);
  EXPECT_NE(message("0,1,2,../etc/passwd,r,0\n").find("field 'left'"), std::string::npos);
  EXPECT_NE(message("0,1,2,l,r\n1,1,1,l,r,0\n").find("line 2 has 5 fields"), std::string::npos);
  try {
    ParseRecordingIndex("", "frames.csv");
    FAIL() << "an empty index must throw";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("no header"), std::string::npos);
  }
  try {
    ParseRecordingIndex("index,time\n", "frames.csv");
    FAIL() << "a wrong header must throw";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("expected header"), std::string::npos);
  }
}

// Indices above 2^53 - 1 are refused where they enter: a line of frames.csv (9223372036854775807 played twice
// numbered frames from -9223372036854775808 before), and the writer, so that it never writes what the reader
// refuses.
TEST(RecordingIndex, IndexAboveTheLargestIsAnErrorNamingTheLine) {
  const std::string header = std::string(kRecordingIndexHeader) + "\n";
  const std::vector<RecordingEntry> entries =
      ParseRecordingIndex(header + "0,1,2,l,r,0\n9007199254740991,1,2,l,r,0\n", "frames.csv");
  ASSERT_EQ(entries.size(), 2u);
  EXPECT_EQ(entries[1].index, kMaxRecordingIndex);
  for (const char* index : {"9007199254740992", "9223372036854775807"}) {
    std::string message = "no error";
    try {
      ParseRecordingIndex(header + "0,1,2,l,r,0\n" + index + ",1,2,l,r,0\n", "frames.csv");
    } catch (const Error& e) {
      message = e.what();
    }
    EXPECT_NE(message.find(std::string("frames.csv: line 3 field 'index' is ") + index +
                           ", above the largest frame index 9007199254740991"),
              std::string::npos)
        << message;
  }
  const TempDir dir("largest");
  StereoFrame frame = TestFrame(0, 8, 4, CV_8UC1);  // (TestFrame's timestamps overflow for such indices)
  frame.index = kMaxRecordingIndex;
  RecordingWriter writer(dir.path() + "/rec", std::nullopt, {});
  writer.Write(frame);
  writer.Finish();
  EXPECT_EQ(OpenRecording(dir.path() + "/rec").frames.at(0).index, kMaxRecordingIndex);
  RecordingWriter second(dir.path() + "/rec2", std::nullopt, {});
  frame.index = kMaxRecordingIndex + 1;
  EXPECT_NE(ErrorOf([&] { second.Write(frame); }).find("is above the largest a recording holds"), std::string::npos);
}

TEST(Recording, MissingCorruptAndMismatchedImagesNameTheFrame) {
  const TempDir dir("bad");
  const std::string folder = dir.path() + "/rec";
  {
    RecordingWriter writer(folder, std::nullopt, {});
    for (int i = 0; i < 4; ++i) writer.Write(TestFrame(i, 32, 16, CV_8UC1));
  }
  fs::remove(folder + "/left/000001.png");
  { std::ofstream(folder + "/right/000002.png") << "not a png"; }
  cv::imwrite(folder + "/right/000003.png", cv::Mat(10, 10, CV_8UC1, cv::Scalar(1)));
  RecordingReadSummary s;
  const Recording rec = OpenRecording(folder, &s);
  EXPECT_EQ(s.missing_files, 1);
  EXPECT_FALSE(rec.files_present[1]);
  EXPECT_NO_THROW(LoadRecordingFrame(rec, 0));
  const std::string missing = LoadError(rec, 1), corrupt = LoadError(rec, 2), sizes = LoadError(rec, 3);
  EXPECT_NE(missing.find("frame 1: left/000001.png is missing"), std::string::npos) << missing;
  EXPECT_NE(corrupt.find("frame 2: right/000002.png is corrupt"), std::string::npos) << corrupt;
  EXPECT_NE(sizes.find("frame 3: left is 32x16 but right is 10x10"), std::string::npos) << sizes;
}

// A PNG of a few bytes whose header declares 65535×65535 16-bit RGBA pixels (32 GiB) is refused before
// anything is allocated for it; so is a file that is no PNG at all (fuzz_recording's inputs).
TEST(Recording, ImagesWhoseHeaderDeclaresMoreThanTheFileHoldsAreRefused) {
  const TempDir dir("bomb");
  const std::string folder = dir.path() + "/rec";
  {
    RecordingWriter writer(folder, std::nullopt, {});
    for (int i = 0; i < 2; ++i) writer.Write(TestFrame(i, 32, 16, CV_8UC1));
  }
  std::string bomb("\x89PNG\r\n\x1a\n\0\0\0\x0dIHDR\0\0\xff\xff\0\0\xff\xff\x10\x06\0\0\0", 29);
  bomb += std::string(40, '\0');
  { std::ofstream(folder + "/right/000000.png", std::ios::binary) << bomb; }
  { std::ofstream(folder + "/left/000001.png", std::ios::binary) << "GIF89a"; }
  const Recording rec = OpenRecording(folder);
  const std::string bomb_error = LoadError(rec, 0), gif_error = LoadError(rec, 1);
  EXPECT_NE(bomb_error.find("frame 0: right/000000.png is corrupt (PNG declares 65535x65535 pixels, more than its 69 "
                            "bytes can hold)"),
            std::string::npos)
      << bomb_error;
  EXPECT_NE(gif_error.find("frame 1: left/000001.png is corrupt (not a PNG image)"), std::string::npos) << gif_error;
}

// Found by fuzz_recording: an index naming a file the file system refuses to look up (a name longer than
// NAME_MAX) threw std::filesystem_error out of OpenRecording; it is a missing file like any other.
TEST(Recording, UnlookupableFileNamesAreMissingFiles) {
  const TempDir dir("longname");
  const std::string folder = dir.path() + "/rec";
  { RecordingWriter writer(folder, std::nullopt, {}); }
  {
    std::ofstream index(folder + "/frames.csv", std::ios::app);
    index << "0,0,0,left/" << std::string(300, 'x') << ".png,right/000000.png,0\n";
  }
  RecordingReadSummary s;
  const Recording rec = OpenRecording(folder, &s);
  EXPECT_EQ(s.missing_files, 1);
  EXPECT_THROW(LoadRecordingFrame(rec, 0), Error);
}

TEST(Recording, WrongRigFileIsOneClearError) {
  const TempDir dir("rig");
  const std::string folder = dir.path() + "/rec";
  { RecordingWriter writer(folder, TestRig(32, 16), {}); }
  { std::ofstream(folder + "/rig.yaml") << "%YAML:1.0\nimage_width: 32\n"; }
  try {
    OpenRecording(folder);
    FAIL() << "a broken rig must throw";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("rig.yaml"), std::string::npos) << e.what();
  }
  EXPECT_THROW(OpenRecording(dir.path() + "/nothing"), Error);
}

// The writer process is killed without warning in the middle of a stream: everything indexed must load.
TEST(Recording, KilledWriterLeavesReadableRecording) {
  const TempDir dir("killed");
  const std::string folder = dir.path() + "/rec";
  int ready[2];
  ASSERT_EQ(pipe(ready), 0);
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    close(ready[0]);
    try {
      RecordingWriter writer(folder, TestRig(64, 48), {{"source", "child"}});
      for (int i = 0;; ++i) {
        writer.Write(TestFrame(i, 64, 48, CV_8UC1));
        if (i == 5) {
          const char c = 'x';
          (void)!write(ready[1], &c, 1);
        }
      }
    } catch (...) {
    }
    _exit(0);
  }
  close(ready[1]);
  char c = 0;
  ASSERT_EQ(read(ready[0], &c, 1), 1);
  close(ready[0]);
  const int status = SignalAndWait(child, SIGKILL);
  ASSERT_TRUE(WIFSIGNALED(status));

  RecordingReadSummary s;
  const Recording rec = OpenRecording(folder, &s);
  EXPECT_GE(rec.num_frames(), 6);
  EXPECT_EQ(rec.meta.at("complete"), "false");
  EXPECT_EQ(s.missing_files, 0);
  ExpectRecordingHoldsTestFrames(rec, 64, 48, CV_8UC1);
  ASSERT_EQ(s.notices.size(), 1u);
  EXPECT_NE(s.notices[0].find("marked incomplete"), std::string::npos) << s.notices[0];
  // Without meta.yaml (or with one that does not say), nothing tells that the writer finished: said so (it was
  // read without a word).
  for (const bool damaged : {false, true}) {
    if (damaged) {
      std::ofstream(folder + "/meta.yaml") << "\x89garbage\n";
    } else {
      std::filesystem::remove(folder + "/meta.yaml");
    }
    RecordingReadSummary again;
    OpenRecording(folder, &again);
    ASSERT_EQ(again.notices.size(), 1u);
    EXPECT_NE(again.notices[0].find(damaged ? "whether the recording is complete is unknown (meta.yaml has no "
                                            : "whether the recording is complete is unknown (no meta.yaml)"),
              std::string::npos)
        << again.notices[0];
  }
}

}  // namespace
}  // namespace rangebayes

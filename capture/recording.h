// Recordings of stereo sessions on disk (format documented in recordings/README.md):
//
//   FOLDER/rig.yaml        StereoRig (calibration/stereo_rig.h); absent when the rig was not calibrated
//   FOLDER/meta.yaml       source description, free `key: "value"` lines
//   FOLDER/frames.csv      header `index,timestamp_left_ns,timestamp_right_ns,left,right,pattern_id`,
//                          one line per complete frame, file names relative to FOLDER
//   FOLDER/left/NNNNNN.png, FOLDER/right/NNNNNN.png   lossless 8- or 16-bit PNG
//   FOLDER/ground_truth/   optional (synthetic recordings): depth_left_m.pfm, disparity_left_px.pfm
//
// The writer appends a frame's line to frames.csv only after both of its images are on disk, and flushes
// the index after every frame, so a recording cut short by a crash or a full disk stays readable up to its
// last complete frame.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "calibration/stereo_rig.h"
#include "capture/file_syscalls.h"
#include "capture/stereo_frame.h"

namespace rangebayes {

inline constexpr const char* kRecordingIndexHeader = "index,timestamp_left_ns,timestamp_right_ns,left,right,pattern_id";

// The largest frame index a recording holds (2^53 - 1, the largest integer a double holds exactly, so that an
// index survives JSON and Python), and the largest a PlaybackSource delivers across repeats and loops.
inline constexpr std::int64_t kMaxRecordingIndex = (std::int64_t{1} << 53) - 1;

// One line of frames.csv.
struct RecordingEntry {
  std::int64_t index = 0;  // 0..kMaxRecordingIndex
  std::int64_t timestamp_left_ns = 0;
  std::int64_t timestamp_right_ns = 0;
  std::string left;   // relative to the recording folder
  std::string right;
  int pattern_id = -1;
};

// Free key/value description of the source (device names, formats, frame rate, generator options).
using RecordingMeta = std::map<std::string, std::string>;

struct RecordingWriterOptions {
  int png_compression = 1;          // 0–9: zlib level of the PNG images (1: fast, files ~10% larger than 9)
  int fsync_every_frames = 0;       // 0: never fsync (a process crash keeps everything flushed; power loss
                                    // may not); n > 0: fsync frames.csv every n frames
  // Allow a folder that already holds a frames.csv: that recording (left/, right/, ground_truth/, frames.csv,
  // meta.yaml, rig.yaml) is removed first.
  bool overwrite = false;
  std::string overwrite_flag;  // the command's option that sets `overwrite`, named in the refusal (may be empty)
  std::shared_ptr<FileSysCalls> files;  // the file system calls; null: the system's (tests inject faults)
  void Check() const;
};

struct RecordingWriterSummary {
  std::int64_t frames_written = 0;
  std::int64_t bytes_written = 0;   // image bytes
  bool finished = false;            // Finish() ran (meta.yaml says complete)
};

// Writes a recording frame by frame. Not thread-safe: one writer thread. Throws Error naming the folder or
// the frame on any write failure (disk full, permissions); frames already written stay readable, and the
// frame whose write failed is not in the index (at most a cut last line, which the reader drops). A failed
// image write leaves no partial file.
class RecordingWriter {
 public:
  // Creates FOLDER (and left/, right/), writes rig.yaml (when `rig` is given), meta.yaml (with
  // `complete: "false"`) and the header of frames.csv. Throws Error if FOLDER already holds a recording
  // and options.overwrite is false.
  RecordingWriter(const std::string& folder, const std::optional<StereoRig>& rig, const RecordingMeta& meta,
                  const RecordingWriterOptions& options = {});
  ~RecordingWriter();  // calls Finish() when the caller did not (errors swallowed there)
  RecordingWriter(const RecordingWriter&) = delete;
  RecordingWriter& operator=(const RecordingWriter&) = delete;

  // Writes both images as FOLDER/left/<index>.png and FOLDER/right/<index>.png (index: the frame's index
  // field, six digits), then appends and flushes its frames.csv line. Indices must increase and stay at most
  // kMaxRecordingIndex. With fsync_every_frames, a failed fsync does not stop the recording (no frame is lost
  // for it); Finish reports it.
  void Write(const StereoFrame& frame);

  // Rewrites meta.yaml with the frame count, `complete: "true"` and `extra` merged in, and closes the index.
  // Safe to call twice; Write after Finish throws. After a Write that failed (the frame was not recorded: a full
  // disk, a folder removed), meta.yaml says `complete: "false"` and `error:` that failure's message (unless
  // `extra` has an error of its own), and Finish returns normally: the caller was told by Write. When frames.csv
  // could not be synced to disk or closed (now or at an earlier fsync), meta.yaml says `complete: "false"` and
  // Finish throws Error naming frames.csv and the system's reason: its last lines may not have reached the disk.
  void Finish(const RecordingMeta& extra = {});

  const std::string& folder() const { return folder_; }
  const RecordingWriterSummary& summary() const { return summary_; }

 private:
  void WriteMeta(const RecordingMeta& meta) const;
  void WriteFrame(const StereoFrame& frame);

  std::string folder_;
  RecordingMeta meta_;
  RecordingWriterOptions options_;
  RecordingWriterSummary summary_;
  std::shared_ptr<FileSysCalls> files_;
  int index_fd_ = -1;
  std::int64_t last_index_ = -1;
  bool index_cut_ = false;  // a write of frames.csv failed part-way: no line may follow
  std::string sync_error_;  // the first failed fsync of frames.csv during Write, for Finish to report
  std::string write_error_;  // the first Write that threw (a frame not recorded), for meta.yaml
};

// What a reader found that is not fatal. Each notice is one line a user can read.
struct RecordingReadSummary {
  bool truncated_last_line = false;  // the last line of frames.csv was cut short (crash) and was ignored
  int missing_files = 0;             // entries whose left or right image is not on disk
  std::vector<std::string> notices;
};

// A recording opened for reading: its rig (if any), meta and index. Images are loaded on demand.
struct Recording {
  std::string folder;
  std::optional<StereoRig> rig;
  RecordingMeta meta;
  std::vector<RecordingEntry> frames;
  std::vector<bool> files_present;   // per entry: both images exist on disk

  int num_frames() const { return static_cast<int>(frames.size()); }
};

// Parses frames.csv text (`source` names it in errors). A truncated last line (no newline and too few
// fields or an unparsable number) is dropped and reported in the summary; any other malformed line (an index
// above kMaxRecordingIndex among them) throws Error naming the line number and the field.
std::vector<RecordingEntry> ParseRecordingIndex(const std::string& text, const std::string& source,
                                                RecordingReadSummary* summary = nullptr);

// Reads FOLDER/meta.yaml (`key: value` lines; quotes removed). Missing file: empty meta.
RecordingMeta ReadRecordingMeta(const std::string& path);

// Opens a recording. Throws Error when FOLDER or frames.csv is missing, when rig.yaml exists but is not a
// valid rig, or on a malformed index line. Missing image files are noted per index, not fatal.
Recording OpenRecording(const std::string& folder, RecordingReadSummary* summary = nullptr);

// Loads entry i (0 ≤ i < num_frames) into a StereoFrame (images unchanged: IMREAD_UNCHANGED). Throws Error
// naming the frame index and file when an image is missing, unreadable or corrupt (not a PNG, or a PNG whose
// header declares more pixels than its file can hold: nothing is allocated for those), or when the left and
// right sizes or types differ.
StereoFrame LoadRecordingFrame(const Recording& recording, int i);

}  // namespace rangebayes

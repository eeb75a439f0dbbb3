#include "capture/recording.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "core/error.h"
#include "core/files.h"
#include "core/image_file.h"

namespace rangebayes {
namespace fs = std::filesystem;

namespace {

std::string ErrnoText() { return std::strerror(errno); }

// Writes all of `data` to `path` via a temporary file and a rename, so a reader never sees half a file.
void WriteFileAtomically(FileSysCalls& files, const std::string& path, const void* data, size_t size) {
  const std::string tmp = path + ".partial";
  const int fd = files.Open(tmp, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  RB_CHECK(fd >= 0, tmp, ": cannot create (", ErrnoText(), ")");
  const char* p = static_cast<const char*>(data);
  size_t left = size;
  while (left > 0) {
    const ssize_t n = files.Write(fd, p, left);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const std::string why = n == 0 ? "no progress" : ErrnoText();
      files.Close(fd);
      ::unlink(tmp.c_str());
      RB_FAIL(path, ": write failed (", why, ")");
    }
    p += n;
    left -= static_cast<size_t>(n);
  }
  if (files.Close(fd) != 0) {
    const std::string why = ErrnoText();
    ::unlink(tmp.c_str());
    RB_FAIL(path, ": close failed (", why, ")");
  }
  if (files.Rename(tmp, path) != 0) {
    const std::string why = ErrnoText();
    ::unlink(tmp.c_str());
    RB_FAIL(path, ": rename failed (", why, ")");
  }
}

void WriteAll(FileSysCalls& files, int fd, const std::string& text, const std::string& what) {
  const char* p = text.data();
  size_t left = text.size();
  while (left > 0) {
    const ssize_t n = files.Write(fd, p, left);
    if (n < 0 && errno == EINTR) continue;
    RB_CHECK(n > 0, what, ": write failed (", n == 0 ? "no progress" : ErrnoText(), ")");
    p += n;
    left -= static_cast<size_t>(n);
  }
}

std::string Quote(const std::string& value) {
  std::string out = "\"";
  for (const char c : value) {
    if (c == '"' || c == '\\') out += '\\';
    if (c == '\n') {
      out += "\\n";
      continue;
    }
    out += c;
  }
  return out + "\"";
}

std::string Trim(const std::string& s) {
  const size_t b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) return "";
  const size_t e = s.find_last_not_of(" \t\r");
  return s.substr(b, e - b + 1);
}

std::string Unquote(const std::string& raw) {
  const std::string s = Trim(raw);
  if (s.size() < 2 || (s.front() != '"' && s.front() != '\'') || s.back() != s.front()) return s;
  std::string out;
  for (size_t i = 1; i + 1 < s.size(); ++i) {
    if (s[i] == '\\' && i + 2 < s.size()) {
      ++i;
      out += s[i] == 'n' ? '\n' : s[i];
    } else {
      out += s[i];
    }
  }
  return out;
}

bool ParseInt64(const std::string& s, std::int64_t* out) {
  const std::string t = Trim(s);
  if (t.empty()) return false;
  const char* end = t.data() + t.size();
  const auto r = std::from_chars(t.data(), end, *out);
  return r.ec == std::errc() && r.ptr == end;
}

std::vector<std::string> SplitComma(const std::string& line) {
  std::vector<std::string> fields;
  size_t start = 0;
  while (true) {
    const size_t comma = line.find(',', start);
    if (comma == std::string::npos) {
      fields.push_back(line.substr(start));
      return fields;
    }
    fields.push_back(line.substr(start, comma - start));
    start = comma + 1;
  }
}

// A file name from frames.csv must stay inside the recording folder.
bool IsSafeRelativePath(const std::string& name) {
  if (name.empty() || name.front() == '/') return false;
  const fs::path p(name);
  for (const auto& part : p) {
    if (part == "..") return false;
  }
  return true;
}

void FrameName(std::int64_t index, char* buffer, size_t size) {
  std::snprintf(buffer, size, "%06lld.png", static_cast<long long>(index));
}

}  // namespace

void RecordingWriterOptions::Check() const {
  RB_CHECK(png_compression >= 0 && png_compression <= 9, "png_compression must be in 0..9, got ", png_compression);
  RB_CHECK(fsync_every_frames >= 0, "fsync_every_frames must be >= 0, got ", fsync_every_frames);
}

RecordingWriter::RecordingWriter(const std::string& folder, const std::optional<StereoRig>& rig,
                                 const RecordingMeta& meta, const RecordingWriterOptions& options)
    : folder_(folder), meta_(meta), options_(options), files_(options.files ? options.files : RealFileSysCalls()) {
  options_.Check();
  RB_CHECK(!folder.empty(), "recording folder name is empty");
  const fs::path root(folder);
  std::error_code ec;
  if (fs::exists(root / "frames.csv", ec)) {
    RB_CHECK(options_.overwrite, folder, ": already holds a recording (frames.csv); choose another folder",
             options_.overwrite_flag.empty() ? "" : ", or " + options_.overwrite_flag + " to replace it");
    // Replaced, not written over: the old frames beyond the new ones (and a synthetic recording's ground truth of
    // another size) stayed beside the new recording.
    for (const char* name : {"left", "right", "ground_truth", "frames.csv", "meta.yaml", "rig.yaml"}) {
      fs::remove_all(root / name, ec);
      RB_CHECK(!ec, folder, "/", name, ": cannot remove the recording it replaces (", ec.message(), ")");
    }
  }
  CreateFolder((root / "left").string());
  CreateFolder((root / "right").string());
  if (rig.has_value()) {
    WriteStereoRig(*rig, (root / "rig.yaml").string());
  } else {
    fs::remove(root / "rig.yaml", ec);
    meta_.emplace("rig", "none (uncalibrated)");
  }
  meta_["complete"] = "false";
  WriteMeta(meta_);
  const std::string index_path = (root / "frames.csv").string();
  index_fd_ = files_->Open(index_path, O_WRONLY | O_CREAT | O_TRUNC | O_APPEND | O_CLOEXEC, 0644);
  RB_CHECK(index_fd_ >= 0, index_path, ": cannot create (", ErrnoText(), ")");
  try {
    WriteAll(*files_, index_fd_, std::string(kRecordingIndexHeader) + "\n", index_path);
  } catch (...) {
    files_->Close(index_fd_);  // the constructor throws: no destructor will close it
    index_fd_ = -1;
    throw;
  }
}

RecordingWriter::~RecordingWriter() {
  try {
    Finish();
  } catch (...) {
    // A destructor must not throw; the recording stays readable up to its last complete frame.
  }
  if (index_fd_ >= 0) files_->Close(index_fd_);
}

void RecordingWriter::WriteMeta(const RecordingMeta& meta) const {
  std::ostringstream out;
  out << "# rangebayes recording: description of the source (see recordings/README.md)\n";
  for (const auto& [key, value] : meta) out << key << ": " << Quote(value) << "\n";
  const std::string text = out.str();
  WriteFileAtomically(*files_, (fs::path(folder_) / "meta.yaml").string(), text.data(), text.size());
}

void RecordingWriter::Write(const StereoFrame& frame) {
  RB_CHECK(!summary_.finished, folder_, ": Write after Finish");
  try {
    WriteFrame(frame);
  } catch (const Error& e) {
    // A recording that missed a frame is not complete (synth and the console's recordings cut short by a full
    // disk said `complete: "true"`).
    if (write_error_.empty()) write_error_ = e.what();
    throw;
  }
}

void RecordingWriter::WriteFrame(const StereoFrame& frame) {
  RB_CHECK(!index_cut_, folder_, ": frame ", frame.index,
           " not recorded: frames.csv was cut by an earlier write failure");
  RB_CHECK(!frame.empty(), folder_, ": frame ", frame.index, " has an empty image");
  RB_CHECK(frame.left.size() == frame.right.size() && frame.left.type() == frame.right.type(), folder_,
           ": frame ", frame.index, ": left and right images differ in size or type");
  RB_CHECK(frame.index > last_index_, folder_, ": frame index ", frame.index, " does not increase (last ",
           last_index_, ")");
  RB_CHECK(frame.index <= kMaxRecordingIndex, folder_, ": frame index ", frame.index,
           " is above the largest a recording holds (", kMaxRecordingIndex, ")");
  const int depth = frame.left.depth();
  RB_CHECK(depth == CV_8U || depth == CV_16U, folder_, ": frame ", frame.index,
           ": only 8-bit or 16-bit images can be recorded");
  char name[32];
  FrameName(frame.index, name, sizeof(name));
  const std::string left_rel = std::string("left/") + name;
  const std::string right_rel = std::string("right/") + name;
  const std::vector<int> params = {cv::IMWRITE_PNG_COMPRESSION, options_.png_compression};
  std::vector<uchar> buffer;
  for (int side = 0; side < 2; ++side) {
    const cv::Mat& image = side == 0 ? frame.left : frame.right;
    const std::string& rel = side == 0 ? left_rel : right_rel;
    bool ok = false;
    try {
      ok = cv::imencode(".png", image, buffer, params);
    } catch (const cv::Exception& e) {
      RB_FAIL(folder_, ": frame ", frame.index, ": cannot encode ", rel, " (", e.err, ")");
    }
    RB_CHECK(ok, folder_, ": frame ", frame.index, ": cannot encode ", rel);
    try {
      WriteFileAtomically(*files_, (fs::path(folder_) / rel).string(), buffer.data(), buffer.size());
    } catch (const Error& e) {
      RB_FAIL(folder_, ": frame ", frame.index, " not recorded: ", e.what());
    }
    summary_.bytes_written += static_cast<std::int64_t>(buffer.size());
  }
  std::ostringstream line;
  line << frame.index << ',' << frame.timestamp_left_ns << ',' << frame.timestamp_right_ns << ',' << left_rel << ','
       << right_rel << ',' << frame.pattern_id << '\n';
  // One write() of the whole line on an O_APPEND descriptor: a crash leaves either the line or nothing
  // (a full disk can leave part of it, which the reader drops).
  try {
    WriteAll(*files_, index_fd_, line.str(), folder_ + "/frames.csv");
  } catch (const Error& e) {
    index_cut_ = true;
    RB_FAIL(folder_, ": frame ", frame.index, " not recorded: ", e.what());
  }
  last_index_ = frame.index;
  ++summary_.frames_written;
  if (options_.fsync_every_frames > 0 && summary_.frames_written % options_.fsync_every_frames == 0 &&
      files_->Fsync(index_fd_) != 0) {
    const std::string why = ErrnoText();
    // Kept for Finish instead of thrown: the recorder would stop, and the frames still to come be lost.
    if (sync_error_.empty()) {
      sync_error_ = StrCat(folder_, "/frames.csv: fsync failed after frame ", frame.index, " (", why, ")");
    }
  }
}

void RecordingWriter::Finish(const RecordingMeta& extra) {
  if (summary_.finished) return;
  summary_.finished = true;
  std::string index_error = sync_error_;
  if (index_fd_ >= 0) {
    const std::string index_path = folder_ + "/frames.csv";
    if (files_->Fsync(index_fd_) != 0) {
      const std::string why = ErrnoText();
      if (index_error.empty()) index_error = StrCat(index_path, ": fsync failed (", why, ")");
    }
    // Not retried when it fails: Linux releases the descriptor whatever close returns.
    if (files_->Close(index_fd_) != 0) {
      const std::string why = ErrnoText();
      if (index_error.empty()) index_error = StrCat(index_path, ": close failed (", why, ")");
    }
    index_fd_ = -1;
  }
  for (const auto& [key, value] : extra) meta_[key] = value;
  meta_["frame_count"] = std::to_string(summary_.frames_written);
  if (index_error.empty() && write_error_.empty()) {
    meta_["complete"] = "true";
    WriteMeta(meta_);
    return;
  }
  if (index_error.empty()) {
    meta_["complete"] = "false";
    if (meta_.count("error") == 0) meta_["error"] = write_error_;
    try {
      WriteMeta(meta_);
    } catch (const Error&) {
      // The disk that refused the frame may refuse meta.yaml too; it keeps its earlier `complete: "false"`.
    }
    return;
  }
  // The frames are still readable up to the last line that reached the disk; the recording is not complete.
  meta_["complete"] = "false";
  try {
    WriteMeta(meta_);
  } catch (const Error&) {
    // The index's error is the one to report; meta.yaml keeps its earlier `complete: "false"`.
  }
  RB_FAIL(index_error);
}

std::vector<RecordingEntry> ParseRecordingIndex(const std::string& text, const std::string& source,
                                                RecordingReadSummary* summary) {
  std::vector<RecordingEntry> entries;
  // A UTF-8 byte order mark (an editor's) before the header is skipped: the header was refused with two strings
  // that printed alike.
  size_t pos = text.starts_with("\xEF\xBB\xBF") ? 3 : 0;
  int line_number = 0;
  bool header_seen = false;
  while (pos < text.size()) {
    const size_t newline = text.find('\n', pos);
    const bool last_without_newline = newline == std::string::npos;
    std::string line = text.substr(pos, last_without_newline ? std::string::npos : newline - pos);
    pos = last_without_newline ? text.size() : newline + 1;
    ++line_number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (Trim(line).empty()) continue;
    if (!header_seen) {
      RB_CHECK(Trim(line) == kRecordingIndexHeader, source, ": line 1: expected header '", kRecordingIndexHeader,
               "', got '", line, "'");
      header_seen = true;
      continue;
    }
    const std::vector<std::string> f = SplitComma(line);
    RecordingEntry e;
    std::int64_t pattern = -1;
    std::string problem;
    if (f.size() != 6) {
      problem = StrCat("has ", f.size(), " fields, expected 6");
    } else if (!ParseInt64(f[0], &e.index) || e.index < 0) {
      problem = StrCat("field 'index' is not a non-negative integer ('", f[0], "')");
    } else if (e.index > kMaxRecordingIndex) {
      problem = StrCat("field 'index' is ", e.index, ", above the largest frame index ", kMaxRecordingIndex);
    } else if (!ParseInt64(f[1], &e.timestamp_left_ns)) {
      problem = StrCat("field 'timestamp_left_ns' is not an integer ('", f[1], "')");
    } else if (!ParseInt64(f[2], &e.timestamp_right_ns)) {
      problem = StrCat("field 'timestamp_right_ns' is not an integer ('", f[2], "')");
    } else if (!IsSafeRelativePath(Trim(f[3]))) {
      problem = StrCat("field 'left' is not a relative path inside the recording ('", f[3], "')");
    } else if (!IsSafeRelativePath(Trim(f[4]))) {
      problem = StrCat("field 'right' is not a relative path inside the recording ('", f[4], "')");
    } else if (!ParseInt64(f[5], &pattern) || pattern < -1 || pattern > 1'000'000) {
      problem = StrCat("field 'pattern_id' is not an integer >= -1 ('", f[5], "')");
    } else if (!entries.empty() && e.index <= entries.back().index) {
      problem = StrCat("index ", e.index, " does not increase (previous ", entries.back().index, ")");
    }
    if (!problem.empty()) {
      if (last_without_newline) {
        // What a crash or a full disk leaves behind: the last frame was not completely indexed.
        if (summary != nullptr) {
          summary->truncated_last_line = true;
          summary->notices.push_back(StrCat(source, ": line ", line_number, " is truncated (", problem,
                                            "); ignored, the recording ends at the frame before it"));
        }
        break;
      }
      RB_FAIL(source, ": line ", line_number, " ", problem);
    }
    e.left = Trim(f[3]);
    e.right = Trim(f[4]);
    e.pattern_id = static_cast<int>(pattern);
    entries.push_back(std::move(e));
  }
  RB_CHECK(header_seen, source, ": empty index (no header line)");
  return entries;
}

RecordingMeta ReadRecordingMeta(const std::string& path) {
  RecordingMeta meta;
  std::ifstream in(path);
  if (!in) return meta;
  std::string line;
  while (std::getline(in, line)) {
    const std::string t = Trim(line);
    if (t.empty() || t.front() == '#' || t.front() == '%' || t == "---") continue;
    const size_t colon = t.find(':');
    if (colon == std::string::npos) continue;
    meta[Trim(t.substr(0, colon))] = Unquote(t.substr(colon + 1));
  }
  return meta;
}

Recording OpenRecording(const std::string& folder, RecordingReadSummary* summary) {
  RecordingReadSummary local;
  RecordingReadSummary& s = summary != nullptr ? *summary : local;
  const fs::path root(folder);
  RB_CHECK(fs::is_directory(root), folder, ": recording folder not found");
  const fs::path index_path = root / "frames.csv";
  RB_CHECK(fs::is_regular_file(index_path), folder, ": not a recording (frames.csv missing)");
  std::ifstream in(index_path, std::ios::binary);
  RB_CHECK(in.good(), index_path.string(), ": cannot open");
  std::ostringstream text;
  text << in.rdbuf();
  Recording rec;
  rec.folder = folder;
  rec.frames = ParseRecordingIndex(text.str(), index_path.string(), &s);
  rec.meta = ReadRecordingMeta((root / "meta.yaml").string());
  const auto complete = rec.meta.find("complete");
  if (complete != rec.meta.end() && complete->second == "false") {
    const auto error = rec.meta.find("error");
    s.notices.push_back(StrCat(folder, ": the recording is marked incomplete (meta.yaml complete: false",
                               error != rec.meta.end() ? "; error: " + error->second : std::string(),
                               "): it may end early or still be written"));
  } else if (complete == rec.meta.end() || complete->second != "true") {
    // A recording made by hand, or a meta.yaml that is missing or damaged: nothing says the writer finished (it
    // was read without a word).
    std::error_code ec;
    const std::string why = !fs::is_regular_file(root / "meta.yaml", ec) ? "no meta.yaml"
                            : complete == rec.meta.end()                 ? "meta.yaml has no 'complete'"
                                                                         : "meta.yaml complete: " + complete->second;
    s.notices.push_back(StrCat(folder, ": whether the recording is complete is unknown (", why, ")"));
  }
  if (fs::exists(root / "rig.yaml")) rec.rig = ReadStereoRig((root / "rig.yaml").string());
  rec.files_present.resize(rec.frames.size(), true);
  for (size_t i = 0; i < rec.frames.size(); ++i) {
    const RecordingEntry& e = rec.frames[i];
    for (const std::string* name : {&e.left, &e.right}) {
      std::error_code ec;  // a name the file system refuses (too long, through a file) is missing, not fatal
      if (!fs::is_regular_file(root / *name, ec)) {
        rec.files_present[i] = false;
        s.notices.push_back(StrCat(folder, ": frame ", e.index, ": ", *name, " is missing"));
      }
    }
    if (!rec.files_present[i]) ++s.missing_files;
  }
  return rec;
}

StereoFrame LoadRecordingFrame(const Recording& recording, int i) {
  RB_CHECK(i >= 0 && i < recording.num_frames(), recording.folder, ": frame position ", i, " out of range [0, ",
           recording.num_frames(), ")");
  const RecordingEntry& e = recording.frames[static_cast<size_t>(i)];
  StereoFrame frame;
  frame.index = e.index;
  frame.timestamp_left_ns = e.timestamp_left_ns;
  frame.timestamp_right_ns = e.timestamp_right_ns;
  frame.pattern_id = e.pattern_id;
  for (int side = 0; side < 2; ++side) {
    const std::string& name = side == 0 ? e.left : e.right;
    const std::string path = (fs::path(recording.folder) / name).string();
    std::error_code ec;
    RB_CHECK(fs::is_regular_file(path, ec), recording.folder, ": frame ", e.index, ": ", name, " is missing");
    std::vector<uchar> bytes;
    {
      std::ifstream in(path, std::ios::binary);
      RB_CHECK(in.good(), recording.folder, ": frame ", e.index, ": ", name, " cannot be read");
      bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    }
    const std::string problem = PngProblem(bytes);
    RB_CHECK(problem.empty(), recording.folder, ": frame ", e.index, ": ", name, " is corrupt (", problem, ")");
    cv::Mat image;
    try {
      image = cv::imdecode(bytes, cv::IMREAD_UNCHANGED);
    } catch (const cv::Exception& ex) {
      RB_FAIL(recording.folder, ": frame ", e.index, ": ", name, " is corrupt (", ex.err, ")");
    }
    RB_CHECK(!image.empty(), recording.folder, ": frame ", e.index, ": ", name, " is corrupt or not an image");
    RB_CHECK(image.depth() == CV_8U || image.depth() == CV_16U, recording.folder, ": frame ", e.index, ": ", name,
             " is neither 8-bit nor 16-bit");
    (side == 0 ? frame.left : frame.right) = image;
  }
  RB_CHECK(frame.left.size() == frame.right.size(), recording.folder, ": frame ", e.index, ": left is ",
           frame.left.cols, "x", frame.left.rows, " but right is ", frame.right.cols, "x", frame.right.rows);
  RB_CHECK(frame.left.type() == frame.right.type(), recording.folder, ": frame ", e.index,
           ": left and right differ in bit depth or channels");
  return frame;
}

}  // namespace rangebayes

#include "console/console.h"

#include <pthread.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <sstream>

#include "core/error.h"
#include "core/json_int.h"
#include "core/json_text.h"
#include "core/mesh_io.h"
#include "pipeline/pipeline_control.h"
#include "stereo/colormap.h"

namespace rangebayes {

namespace fs = std::filesystem;

namespace {

using Clock = std::chrono::steady_clock;

double NowS() { return std::chrono::duration<double>(Clock::now().time_since_epoch()).count(); }

std::int64_t UnixMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

HttpReply JsonReply(int status, const nlohmann::json& body) {
  HttpReply r;
  r.status = status;
  r.body = JsonText(body);
  return r;
}

HttpReply ErrorReply(int status, const std::string& message) { return JsonReply(status, {{"error", message}}); }

std::string Jpeg(const cv::Mat& bgr_or_grey, int quality) {
  cv::Mat img = bgr_or_grey;
  if (img.depth() == CV_16U) img.convertTo(img, CV_8U, 1.0 / 256.0);
  std::vector<unsigned char> bytes;
  cv::imencode(".jpg", img, bytes, {cv::IMWRITE_JPEG_QUALITY, quality});
  return std::string(bytes.begin(), bytes.end());
}

cv::Mat RgbToBgrMat(const RgbImage& image) {
  cv::Mat rgb(image.height, image.width, CV_8UC3, const_cast<std::uint8_t*>(image.rgb.data()));
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  return bgr;
}

// The 1st and 99th percentile of the finite values (the colour scale shown beside the map); nullopt if none.
std::optional<std::pair<double, double>> Range(const cv::Mat& values) {
  if (values.empty() || values.type() != CV_32F) return std::nullopt;
  std::vector<float> v;
  v.reserve(values.total());
  for (int y = 0; y < values.rows; ++y) {
    const float* row = values.ptr<float>(y);
    for (int x = 0; x < values.cols; ++x) {
      if (std::isfinite(row[x])) v.push_back(row[x]);
    }
  }
  if (v.empty()) return std::nullopt;
  const auto at = [&](double q) {
    const size_t k = std::min(v.size() - 1, static_cast<size_t>(q * static_cast<double>(v.size() - 1)));
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
    return static_cast<double>(v[k]);
  };
  double lo = at(0.01), hi = at(0.99);
  if (!(hi > lo)) hi = lo + 1e-6;
  return std::make_pair(lo, hi);
}

const char* MatcherName(PipelineMatcher m) { return m == PipelineMatcher::kSgbm ? "sgbm" : "spacetime"; }

}  // namespace

// A recording started from the page: a writer thread fed by a dropping queue.
struct Console::Recording {
  std::string name;
  std::string folder;
  std::unique_ptr<RecordingWriter> writer;
  BoundedQueue<StereoFrame> queue;
  std::atomic<std::int64_t> written{0};
  std::string error;  // the writer thread's, once it stopped on one
  std::mutex error_mutex;
  std::thread thread;

  explicit Recording(int capacity) : queue(static_cast<size_t>(capacity), QueueFullPolicy::kDropOldest) {}
};

void ConsoleOptions::Check() const {
  server.Check();
  wire_mesh.Check();
  RB_CHECK(jpeg_quality >= 1 && jpeg_quality <= 100, "console: jpeg_quality must be in 1..100");
  RB_CHECK(status_period_s > 0.0, "console: status_period_s must be > 0");
  RB_CHECK(record_queue_frames >= 1, "console: record_queue_frames must be >= 1");
  RB_CHECK(!record_root.empty() && !capture_dir.empty(), "console: record_root and capture_dir must be given");
}

Console::Console(const ConsoleOptions& options, PipelineControl* control, std::optional<StereoRig> rig,
                 RecordingMeta meta)
    : options_(options), control_(control), rig_(std::move(rig)), meta_(std::move(meta)) {
  options_.Check();
  token_ = options_.token.empty() ? MakeConsoleToken() : options_.token;
  instance_ = MakeConsoleToken().substr(0, 12);  // drawn apart from the token, which the status must not reveal
  started_unix_ms_ = UnixMs();
  assets_ = LoadConsoleAssets(options_.three_dir);
  {
    cv::Mat ramp(1, 256, CV_32F);
    for (int i = 0; i < 256; ++i) ramp.at<float>(0, i) = static_cast<float>(i) / 255.0f;
    ColorMapOptions c;
    c.min_value = 0.0;
    c.max_value = 1.0;
    std::vector<unsigned char> png;
    cv::imencode(".png", RgbToBgrMat(ColorMap(ramp, c)), png);
    colorbar_png_ = std::make_shared<const std::string>(png.begin(), png.end());
  }
  if (options_.server.default_subscriptions.empty()) options_.server.default_subscriptions = {{"mesh", "smoothed"}};
  server_ = std::make_unique<ConsoleServer>(options_.server, [this](const HttpRequest& r) { return Handle(r); });
  worker_ = std::thread([this] {
    pthread_setname_np(pthread_self(), "rb-console");  // so that a profile tells the console's CPU apart
    Work();
  });
}

Console::~Console() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  if (worker_.joinable()) worker_.join();
  server_->Stop();
  StopRecording();
}

std::string Console::url() const {
  std::string a = server_->address();
  if (a == "0.0.0.0" || a == "::") {
    // Every interface: the address others reach it at is this machine's name (0.0.0.0 is no address to open).
    char name[256] = {};
    if (::gethostname(name, sizeof(name) - 1) == 0 && name[0] != '\0') a = name;
  }
  const std::string host = a.find(':') != std::string::npos ? "[" + a + "]" : a;
  return StrCat("http://", host, ":", server_->port(), "/");
}

void Console::Consume(const PipelineResult& result) {
  auto copy = std::make_shared<const PipelineResult>(result);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    ++results_in_;
    const double now = NowS();
    result_times_s_.push_back(now);
    while (!result_times_s_.empty() && result_times_s_.front() < now - 3.0) result_times_s_.pop_front();
    if (result.full_quality) {
      full_quality_.push_back(copy);
    }
    if (latest_) ++results_skipped_;
    latest_ = std::move(copy);
  }
  wake_.notify_one();
}

void Console::Finish() {
  StopRecording();
  PipelineSnapshot snap;
  if (control_ != nullptr) snap = control_->Snapshot();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    finished_ = true;
    // Every result has been consumed and counted: a capture still pending, with no full-quality result or failure
    // counted since the request, will never come. (The counts, not full_quality_: the worker may be saving the
    // last capture right now.)
    if (capture_pending_ && snap.full_quality_done == capture_done_before_ &&
        snap.full_quality_failed == capture_failed_before_) {
      capture_pending_ = false;
      last_capture_error_ = "the run ended before a frame was taken at full quality: no capture";
    }
  }
  wake_.notify_one();
}

void Console::OnFrame(const StereoFrame& frame) {
  std::lock_guard<std::mutex> lock(record_mutex_);
  if (!recording_) return;
  // The recorder gets its own pixels. A shallow copy would share the buffers with the pipeline, which releases
  // (and a source may reuse) them while the writer thread is still encoding the PNG; the ownership hand-over
  // then rests on cv::Mat's reference count inside OpenCV, which ThreadSanitizer cannot follow and which does
  // not protect against a source that writes into a buffer it hands out again. One copy per recorded frame.
  StereoFrame own = frame;
  own.left = frame.left.clone();
  own.right = frame.right.clone();
  recording_->queue.Push(std::move(own));
}

void Console::Work() {
  auto next_status = Clock::now();
  for (;;) {
    std::shared_ptr<const PipelineResult> result, full;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait_until(lock, next_status, [&] { return stopping_ || latest_ || !full_quality_.empty(); });
      // A capture the pipeline delivered is saved even when the console is going away (a run stopped by Ctrl-C
      // delivers the capture it had finished).
      if (stopping_ && full_quality_.empty()) return;
      if (!stopping_) result = std::move(latest_);
      latest_.reset();
      if (!full_quality_.empty()) {
        full = full_quality_.front();
        full_quality_.pop_front();
      }
    }
    if (full) SaveCapture(*full);
    if (result) Publish(*result);
    if (Clock::now() >= next_status) {
      BroadcastStatus();
      next_status = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                       std::chrono::duration<double>(options_.status_period_s));
    }
  }
}

void Console::Publish(const PipelineResult& r) {
  const auto send = [&](ConsoleMessageType type, const nlohmann::json& header, const std::string& payload,
                        const std::string& topic) {
    server_->Broadcast(std::make_shared<const std::string>(EncodeConsoleMessage(type, header, payload)),
                       /*binary=*/true, topic);
  };
  // Only what some client takes now is encoded (server.h: Wants).
  if (!r.left_rectified.empty() && server_->Wants("image/left")) {
    send(ConsoleMessageType::kImage, {{"kind", "left"}, {"frame", r.index}, {"format", "jpeg"}},
         Jpeg(r.left_rectified, options_.jpeg_quality), "image/left");
  }
  const auto map = [&](const char* kind, const cv::Mat& values, bool reverse) {
    if (values.empty() || !server_->Wants(StrCat("image/", kind))) return;
    const auto range = Range(values);
    if (!range) return;
    ColorMapOptions c;
    c.min_value = range->first;
    c.max_value = range->second;
    c.reverse = reverse;
    send(ConsoleMessageType::kImage,
         {{"kind", kind}, {"frame", r.index}, {"format", "jpeg"}, {"min", range->first}, {"max", range->second},
          {"unit", "m"}, {"reverse", reverse}},
         Jpeg(RgbToBgrMat(ColorMap(values, c)), options_.jpeg_quality), StrCat("image/", kind));
  };
  map("depth", r.depth.depth_m, /*reverse=*/true);
  map("sigma", r.depth.sigma_depth_m, /*reverse=*/false);
  const std::int64_t now_ns =
      std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch()).count();
  const double age_ms = r.entered_steady_ns > 0 ? 1e-6 * static_cast<double>(now_ns - r.entered_steady_ns) : 0.0;
  std::vector<std::string> kinds;
  const auto mesh = [&](const char* kind, const Mesh& m) {
    if (m.num_faces() == 0) return;
    kinds.push_back(kind);
    if (!server_->Wants(StrCat("mesh/", kind))) return;
    const Mesh wire = WireMesh(m, options_.wire_mesh);
    send(ConsoleMessageType::kMesh,
         {{"kind", kind},
          {"frame", r.index},
          {"vertices", wire.num_vertices()},
          {"faces", wire.num_faces()},
          {"source_faces", m.num_faces()},
          {"full_quality", r.full_quality},
          {"age_ms", age_ms},
          {"sent_unix_ms", UnixMs()}},
         EncodeMeshPayload(wire), StrCat("mesh/", kind));
  };
  mesh("raw", r.raw_mesh.mesh);
  if (r.smoothed) mesh("smoothed", *r.smoothed);
  if (r.decimated) mesh("decimated", r.decimated->mesh);
  std::lock_guard<std::mutex> lock(mutex_);
  ++published_;
  latest_frame_ = r.index;
  latency_ms_ = age_ms;
  mesh_kinds_ = kinds;
}

void Console::SaveCapture(const PipelineResult& r) {
  const Mesh& m = r.smoothed ? *r.smoothed : r.raw_mesh.mesh;
  Capture c;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    c.id = next_capture_id_++;
  }
  c.frame = r.index;
  c.vertices = m.num_vertices();
  c.faces = m.num_faces();
  try {
    fs::create_directories(options_.capture_dir);
    c.path = (fs::path(options_.capture_dir) / StrCat("capture_", c.id, ".ply")).string();
    WriteMesh(m, c.path);
  } catch (const std::exception& e) {
    std::lock_guard<std::mutex> lock(mutex_);
    last_capture_error_ = e.what();
    capture_pending_ = false;
    return;
  }
  nlohmann::json msg = {{"type", "capture"},  {"id", c.id},         {"frame", c.frame},
                        {"faces", c.faces},   {"vertices", c.vertices},
                        {"url", StrCat("/api/capture/", c.id, ".ply")}};
  {
    std::lock_guard<std::mutex> lock(mutex_);
    captures_.push_back(c);
    capture_pending_ = false;
  }
  server_->Broadcast(std::make_shared<const std::string>(JsonText(msg)), /*binary=*/false, "capture");
}

void Console::BroadcastStatus() {
  nlohmann::json s = Status();
  s["type"] = "status";
  server_->Broadcast(std::make_shared<const std::string>(JsonText(s)), /*binary=*/false, "status");
}

nlohmann::json Console::RecordingStatus() const {
  nlohmann::json j;
  std::error_code ec;
  const fs::path root = fs::exists(options_.record_root, ec) ? fs::path(options_.record_root) : fs::path(".");
  const fs::space_info space = fs::space(root, ec);
  j["disk_free_bytes"] = ec ? -1.0 : static_cast<double>(space.available);
  std::lock_guard<std::mutex> lock(record_mutex_);
  if (recording_) {
    j["active"] = true;
    j["name"] = recording_->name;
    j["folder"] = recording_->folder;
    j["frames_written"] = recording_->written.load();
    j["frames_dropped"] = recording_->queue.dropped();
    std::lock_guard<std::mutex> error_lock(recording_->error_mutex);
    j["error"] = recording_->error;
  } else {
    j["active"] = false;
    j["last"] = last_recording_;
  }
  return j;
}

nlohmann::json Console::Status() const {
  nlohmann::json j;
  PipelineSnapshot snap;
  PipelineSettings settings;
  if (control_ != nullptr) {
    snap = control_->Snapshot();
    settings = control_->settings();
  }
  j["running"] = snap.running;
  j["frames_in"] = snap.frames_captured;
  j["results"] = snap.results;
  j["dropped"] = snap.dropped;
  j["failed"] = snap.failed;
  j["skipped"] = snap.frames_skipped;
  j["timeouts"] = snap.timeouts;
  j["wall_s"] = snap.wall_s;
  j["full_quality_done"] = snap.full_quality_done;
  nlohmann::json stages = nlohmann::json::array();
  for (const StageTiming& t : snap.stages) {
    stages.push_back({{"name", t.name}, {"items", t.items}, {"errors", t.errors}, {"mean_ms", t.mean_ms()},
                      {"max_ms", t.max_ms}});
  }
  j["stages"] = stages;
  j["queue_fill"] = snap.queue_fill;
  j["queue_capacity"] = snap.queue_capacity;
  j["errors"] = snap.errors;
  j["controls"] = control_ != nullptr;
  j["settings"] = {{"paused", settings.paused},
                   {"smooth_budget_ms", settings.smooth_budget_ms},
                   {"stereo_downsample", settings.stereo_downsample},
                   {"matcher", MatcherName(settings.matcher)},
                   {"window_frames", settings.window_frames}};
  j["recording"] = RecordingStatus();
  const ConsoleServerStats server = server_->stats();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const double now = NowS();
    size_t recent = 0;
    for (const double t : result_times_s_) recent += t >= now - 2.0 ? 1 : 0;
    j["fps"] = static_cast<double>(recent) / 2.0;
    j["finished"] = finished_;
    j["latest_frame"] = latest_frame_;
    j["latency_ms"] = latency_ms_;
    j["mesh_kinds"] = mesh_kinds_;
    nlohmann::json captures = nlohmann::json::array();
    for (const Capture& c : captures_) {
      captures.push_back({{"id", c.id}, {"frame", c.frame}, {"faces", c.faces}, {"vertices", c.vertices},
                          {"url", StrCat("/api/capture/", c.id, ".ply")}});
    }
    j["captures"] = captures;
    const bool capture_failed = capture_pending_ && snap.full_quality_failed > capture_failed_before_;
    j["capture_pending"] = capture_pending_ && !capture_failed;
    j["capture_error"] = capture_failed ? StrCat("the full-quality frame failed, no capture: ", snap.full_quality_error)
                                        : last_capture_error_;
    j["instance"] = instance_;
    j["started_unix_ms"] = started_unix_ms_;
    j["console"] = {{"clients", server.clients},
                    {"results_in", results_in_},
                    {"results_published", published_},
                    {"results_skipped", results_skipped_},
                    {"messages_sent", server.messages_sent},
                    {"messages_dropped", server.messages_dropped},
                    {"messages_coalesced", server.messages_coalesced},
                    {"refused", server.refused},
                    {"idle_closed", server.idle_closed}};
  }
  return j;
}

HttpReply Console::Handle(const HttpRequest& request) {
  const std::string path = request.target.substr(0, request.target.find('?'));
  if (path == "/api/control") {
    if (request.method != "POST") return ErrorReply(405, "POST only");
    return Control(request);
  }
  if (request.method != "GET" && request.method != "HEAD") return ErrorReply(405, "GET only");
  if (path == "/api/status") return JsonReply(200, Status());
  if (path == "/api/colorbar.png") {
    HttpReply r;
    r.content_type = "image/png";
    r.body = *colorbar_png_;
    return r;
  }
  const std::string capture_prefix = "/api/capture/";
  if (path.rfind(capture_prefix, 0) == 0) {
    std::string path_on_disk;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      for (const Capture& c : captures_) {
        if (path == StrCat(capture_prefix, c.id, ".ply")) path_on_disk = c.path;
      }
    }
    if (path_on_disk.empty()) return ErrorReply(404, "no such capture");
    std::ifstream in(path_on_disk, std::ios::binary);
    if (!in.good()) return ErrorReply(404, "capture file is gone");
    std::ostringstream body;
    body << in.rdbuf();
    HttpReply r;
    r.content_type = "application/octet-stream";
    r.body = body.str();
    r.headers.push_back({"Content-Disposition", StrCat("attachment; filename=\"", fs::path(path_on_disk).filename().string(), "\"")});
    return r;
  }
  const auto it = assets_.find(path);
  if (it == assets_.end()) return ErrorReply(404, "not found");
  HttpReply r;
  r.content_type = it->second.content_type;
  r.body = *it->second.body;
  return r;
}

HttpReply Console::Control(const HttpRequest& request) {
  const auto t = request.headers.find("x-rangebayes-token");
  if (t == request.headers.end() || !ConstantTimeEqual(t->second, token_)) {
    return ErrorReply(403, "wrong or missing control token (the process printed it at start)");
  }
  const nlohmann::json j = nlohmann::json::parse(request.body, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded() || !j.is_object() || !j.contains("cmd") || !j["cmd"].is_string()) {
    return ErrorReply(400, "malformed command: expected a JSON object with a string \"cmd\"");
  }
  const std::string cmd = j["cmd"].get<std::string>();
  if (cmd == "record_stop") return StopRecording();
  bool finished = false;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    finished = finished_;
  }
  // A finished run takes no more frames: a pause, a capture or a recording would wait for one forever.
  if (finished) return ErrorReply(409, StrCat(cmd, ": the run has finished; restart the process to go on"));
  if (cmd == "record_start") {
    if (!j.contains("name") || !j["name"].is_string()) return ErrorReply(400, "record_start needs a \"name\"");
    return StartRecording(j["name"].get<std::string>());
  }
  if (control_ == nullptr) return ErrorReply(409, "this run takes no pipeline controls");
  try {
    if (cmd == "pause" || cmd == "resume") {
      control_->SetPaused(cmd == "pause");
    } else if (cmd == "capture_now") {
      const PipelineSnapshot snap = control_->Snapshot();
      control_->RequestFullQuality();
      std::lock_guard<std::mutex> lock(mutex_);
      if (!capture_pending_ || snap.full_quality_failed > capture_failed_before_) {
        capture_failed_before_ = snap.full_quality_failed;
        capture_done_before_ = snap.full_quality_done;
      }
      capture_pending_ = true;
      last_capture_error_.clear();
    } else if (cmd == "set") {
      if (j.contains("smooth_budget_ms")) {
        if (!j["smooth_budget_ms"].is_number()) return ErrorReply(400, "smooth_budget_ms must be a number");
        control_->SetSmoothBudgetMs(j["smooth_budget_ms"].get<double>());
      }
      if (j.contains("stereo_downsample")) {
        const std::optional<int> factor = JsonInt(j["stereo_downsample"]);
        if (!factor) return ErrorReply(400, "stereo_downsample must be 1, 2, 4 or 8");
        control_->SetStereoDownsample(*factor);
      }
      if (j.contains("matcher") || j.contains("window_frames")) {
        const PipelineSettings now = control_->settings();
        PipelineMatcher m = now.matcher;
        int w = now.window_frames;
        if (j.contains("matcher")) {
          const nlohmann::json& v = j["matcher"];
          if (!v.is_string() || (v != "sgbm" && v != "spacetime")) {
            return ErrorReply(400, "matcher must be \"sgbm\" or \"spacetime\"");
          }
          m = v == "sgbm" ? PipelineMatcher::kSgbm : PipelineMatcher::kSpaceTime;
          if (m == PipelineMatcher::kSgbm) w = 1;
        }
        if (j.contains("window_frames")) {
          const std::optional<int> frames = JsonInt(j["window_frames"]);
          if (!frames) return ErrorReply(400, "window_frames must be an integer from 1 to 256");
          w = *frames;
        }
        control_->SetMatcher(m, w);
      }
    } else {
      return ErrorReply(400, StrCat("unknown command \"", cmd, "\""));
    }
  } catch (const Error& e) {
    return ErrorReply(400, e.what());
  }
  return JsonReply(200, {{"ok", true}, {"settings", Status()["settings"]}});
}

HttpReply Console::StartRecording(const std::string& name) {
  if (!IsValidRecordingName(name)) {
    return ErrorReply(400, "recording name: 1-64 characters of letters, digits, '.', '_', '-', not starting with '.'");
  }
  std::lock_guard<std::mutex> lock(record_mutex_);
  if (recording_) return ErrorReply(409, StrCat("already recording into ", recording_->folder));
  const std::string folder = (fs::path(options_.record_root) / name).string();
  auto rec = std::make_unique<Recording>(options_.record_queue_frames);
  rec->name = name;
  rec->folder = folder;
  try {
    fs::create_directories(options_.record_root);
    rec->writer = std::make_unique<RecordingWriter>(folder, rig_, meta_);
  } catch (const std::exception& e) {
    return ErrorReply(409, e.what());
  }
  Recording* r = rec.get();
  rec->thread = std::thread([r] {
    while (auto frame = r->queue.Pop()) {
      try {
        r->writer->Write(*frame);
        ++r->written;
      } catch (const std::exception& e) {
        std::lock_guard<std::mutex> error_lock(r->error_mutex);
        r->error = e.what();
        r->queue.Close();
      }
    }
  });
  recording_ = std::move(rec);
  return JsonReply(200, {{"ok", true}, {"folder", folder}});
}

HttpReply Console::StopRecording() {
  std::unique_ptr<Recording> rec;
  {
    std::lock_guard<std::mutex> lock(record_mutex_);
    rec = std::move(recording_);
  }
  if (!rec) return ErrorReply(409, "not recording");
  rec->queue.Close();
  if (rec->thread.joinable()) rec->thread.join();
  std::string error = rec->error;
  try {
    rec->writer->Finish();
  } catch (const std::exception& e) {
    if (error.empty()) error = e.what();
  }
  nlohmann::json summary = {{"name", rec->name},
                            {"folder", rec->folder},
                            {"frames_written", rec->written.load()},
                            {"frames_dropped", rec->queue.dropped()},
                            {"error", error}};
  {
    std::lock_guard<std::mutex> lock(record_mutex_);
    last_recording_ = summary;
  }
  summary["ok"] = error.empty();
  return JsonReply(error.empty() ? 200 : 500, summary);
}

}  // namespace rangebayes

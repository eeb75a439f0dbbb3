// The console's server and HTTP API over real loopback sockets: status JSON fields, the page's files and
// nothing else (traversal attempts), request and message limits, malformed messages, the control token,
// recording and capture through the API, and back-pressure: a client that never reads loses its own
// oldest messages (counted) while frames keep flowing through the pipeline.
#include "console/console.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/time.h>
#include <unistd.h>

#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <filesystem>
#include <thread>
#include <vector>

#include "capture/playback_source.h"
#include "capture/recording.h"
#include "console/server.h"
#include "pipeline/pipeline_control.h"
#include "tests/capture/test_util.h"
#include "tests/console/soak_clients.h"

namespace rangebayes {
namespace {

namespace beast = boost::beast;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;

constexpr const char* kRecording = "recordings/synth_planes_320x240";

tcp::endpoint Local(int port) { return {net::ip::make_address("127.0.0.1"), static_cast<unsigned short>(port)}; }

// Sends `request` as is and returns everything the server answers until it closes.
std::string Exchange(int port, const std::string& request) {
  net::io_context ioc;
  tcp::socket s(ioc);
  s.connect(Local(port));
  net::write(s, net::buffer(request));
  std::string out;
  std::array<char, 4096> buf{};
  beast::error_code ec;
  for (;;) {
    const size_t n = s.read_some(net::buffer(buf), ec);
    if (ec) break;
    out.append(buf.data(), n);
  }
  return out;
}

int StatusOf(const std::string& response) {
  return response.size() > 12 && response.rfind("HTTP/1.1 ", 0) == 0 ? std::stoi(response.substr(9, 3)) : -1;
}

std::string BodyOf(const std::string& response) {
  const size_t at = response.find("\r\n\r\n");
  return at == std::string::npos ? "" : response.substr(at + 4);
}

std::string Get(int port, const std::string& target) {
  return Exchange(port, "GET " + target + " HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n");
}

std::string Post(int port, const std::string& body, const std::string& token) {
  return Exchange(port, "POST /api/control HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n" +
                            (token.empty() ? std::string() : "X-Rangebayes-Token: " + token + "\r\n") +
                            "Content-Type: application/json\r\nContent-Length: " + std::to_string(body.size()) +
                            "\r\n\r\n" + body);
}

#ifndef RB_TEST_TIMEOUT_FACTOR
#define RB_TEST_TIMEOUT_FACTOR 1  // set by tests/console/CMakeLists.txt
#endif

template <typename Predicate>
bool WaitFor(Predicate done, double seconds = 20.0) {
  const auto end =
      std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds * RB_TEST_TIMEOUT_FACTOR);
  while (std::chrono::steady_clock::now() < end) {
    if (done()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return done();
}

ConsoleOptions TestOptions(const TempDir& dir) {
  ConsoleOptions o;
  o.record_root = dir.path() + "/recordings";
  o.capture_dir = dir.path() + "/captures";
  o.token = "0123456789abcdef0123456789abcdef";
  o.status_period_s = 0.05;
  return o;
}

PipelineOptions FastOptions() {
  PipelineOptions p;
  p.stereo_downsample = 2;
  p.triangulate.downsample = 2;
  p.smoothing.tolerance = SmoothTolerance::kFast;
  p.smoothing.max_iterations = 5;
  p.decimate = false;
  p.full_quality_triangulate_downsample = 4;  // keeps the full-quality frame of the test short
  return p;
}

class ConsoleTest : public ::testing::Test {
 protected:
  ConsoleTest() : dir_("console"), recording_(OpenRecording(kRecording)) {
    console_ = std::make_unique<Console>(TestOptions(dir_), &control_, recording_.rig, RecordingMeta{});
  }
  // The recording replayed `repeats` times through the pipeline with the console as its sink.
  PipelineSummary ReplayThroughConsole(int repeats) {
    PlaybackOptions playback;
    playback.repeats = repeats;
    PlaybackSource source(recording_, playback);
    PipelineOptions options = FastOptions();
    options.control = &control_;
    return RunPipeline(source, *recording_.rig, options, {console_.get()});
  }
  TempDir dir_;
  Recording recording_;
  PipelineControl control_;
  std::unique_ptr<Console> console_;
};

TEST_F(ConsoleTest, StatusHasTheIssuesFieldsAndFollowsTheRun) {
  const std::string before = Get(console_->port(), "/api/status");
  ASSERT_EQ(StatusOf(before), 200) << before;
  const nlohmann::json j0 = nlohmann::json::parse(BodyOf(before));
  for (const char* field : {"frames_in", "results", "dropped", "failed", "stages", "recording", "fps", "queue_fill",
                            "errors", "settings", "console"}) {
    EXPECT_TRUE(j0.contains(field)) << field;
  }
  EXPECT_FALSE(j0["running"]);
  // A recording started from the API during the run, and a full-quality capture.
  ASSERT_EQ(StatusOf(Post(console_->port(), R"({"cmd":"record_start","name":"api_rec"})", TestOptions(dir_).token)),
            200);
  control_.RequestFullQuality();
  PlaybackSource source(recording_);
  PipelineOptions options = FastOptions();
  options.control = &control_;
  options.on_frame = [this](const StereoFrame& f) { console_->OnFrame(f); };
  const PipelineSummary s = RunPipeline(source, *recording_.rig, options, {console_.get()});
  ASSERT_EQ(s.results, 8);
  ASSERT_TRUE(WaitFor([&] { return !console_->Status()["captures"].empty(); }));
  const nlohmann::json j = nlohmann::json::parse(BodyOf(Get(console_->port(), "/api/status")));
  EXPECT_EQ(j["frames_in"], 8);
  EXPECT_EQ(j["results"], 8);
  EXPECT_EQ(j["dropped"], 0);
  EXPECT_EQ(j["failed"], 0);
  ASSERT_EQ(j["stages"].size(), 7u);
  EXPECT_EQ(j["stages"][2]["name"], "stereo");
  EXPECT_GT(j["stages"][2]["mean_ms"].get<double>(), 0.0);
  EXPECT_FALSE(j["recording"]["active"]);  // Finish() stopped it
  EXPECT_EQ(j["recording"]["last"]["frames_written"], 8);
  EXPECT_GT(j["recording"]["disk_free_bytes"].get<double>(), 0.0);
  const Recording written = OpenRecording(dir_.path() + "/recordings/api_rec");
  EXPECT_EQ(written.num_frames(), 8);
  const std::string ply = Get(console_->port(), j["captures"][0]["url"].get<std::string>());
  EXPECT_EQ(StatusOf(ply), 200);
  EXPECT_EQ(BodyOf(ply).rfind("ply\n", 0), 0u);
}

// A frame skipped for a file whose name is not UTF-8 (a valid Linux name) puts that name in the status's errors;
// the status is sent with U+FFFD for the byte. json::dump threw there: /api/status answered 500, and the periodic
// status broadcast ended the process (an exception out of the console's thread). A WebSocket client waits for a
// broadcast status that carries the error: the broadcast ran with the name in it.
TEST_F(ConsoleTest, StatusWithAFileNameThatIsNotUtf8) {
  net::io_context ioc;
  websocket::stream<tcp::socket> ws(ioc);
  ws.next_layer().connect(Local(console_->port()));
  ws.handshake("127.0.0.1", "/ws");
  // A read that waits longer than the test's bound ends with an error instead of hanging.
  const timeval read_timeout{static_cast<time_t>(20 * RB_TEST_TIMEOUT_FACTOR), 0};
  ASSERT_EQ(setsockopt(ws.next_layer().native_handle(), SOL_SOCKET, SO_RCVTIMEO, &read_timeout, sizeof read_timeout),
            0);
  Recording rec = recording_;
  rec.frames[1].left = "left/\xff.png";
  PlaybackOptions playback;
  playback.count = 2;
  PlaybackSource source(rec, playback);
  PipelineOptions options = FastOptions();
  options.control = &control_;
  const PipelineSummary s = RunPipeline(source, *rec.rig, options, {console_.get()});
  ASSERT_EQ(s.frames_skipped, 1);
  const std::string expected = "frame 1: left/\xEF\xBF\xBD.png is missing";
  bool broadcast = false;
  beast::flat_buffer buffer;
  beast::error_code ec;
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(20.0 * RB_TEST_TIMEOUT_FACTOR);
  while (!broadcast && !ec && std::chrono::steady_clock::now() < end) {
    ws.read(buffer, ec);
    if (!ec && ws.got_text()) {
      const nlohmann::json m = nlohmann::json::parse(beast::buffers_to_string(buffer.data()));
      broadcast = m.value("type", "") == "status" && m["errors"].size() == 1 &&
                  m["errors"][0].get<std::string>().find(expected) != std::string::npos;
    }
    buffer.consume(buffer.size());
  }
  EXPECT_TRUE(broadcast) << ec.message();
  const std::string reply = Get(console_->port(), "/api/status");
  ASSERT_EQ(StatusOf(reply), 200) << reply;
  const nlohmann::json j = nlohmann::json::parse(BodyOf(reply));
  ASSERT_EQ(j["errors"].size(), 1u) << j["errors"];
  EXPECT_NE(j["errors"][0].get<std::string>().find("frame 1: left/\xEF\xBF\xBD.png is missing"), std::string::npos)
      << j["errors"][0];
}

TEST_F(ConsoleTest, ServesThePageAndNothingElse) {
  EXPECT_EQ(StatusOf(Get(console_->port(), "/")), 200);
  EXPECT_NE(Get(console_->port(), "/").find("text/html"), std::string::npos);
  EXPECT_EQ(StatusOf(Get(console_->port(), "/console.js")), 200);
  EXPECT_EQ(StatusOf(Get(console_->port(), "/three/build/three.module.js")), 200);
  EXPECT_EQ(StatusOf(Get(console_->port(), "/three/examples/jsm/controls/OrbitControls.js")), 200);
  for (const std::string bad :
       {"/../../../../etc/passwd", "/%2e%2e/%2e%2e/etc/passwd", "/three/../../../../etc/passwd",
        "/three/build/../../../../../../etc/passwd", "//etc/passwd", "/three/build/three.js", "/console.js/..",
        "/.%2e/.%2e/etc/passwd", "/api/capture/../../etc/passwd", "/api/capture/1.ply", "/three/"}) {
    const std::string r = Get(console_->port(), bad);
    EXPECT_EQ(StatusOf(r), 404) << bad;
    EXPECT_EQ(r.find("root:"), std::string::npos) << bad;
  }
  EXPECT_EQ(StatusOf(Exchange(console_->port(),
                              "GET ../etc/passwd HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n")),
            404);
  EXPECT_EQ(StatusOf(Exchange(console_->port(), "DELETE / HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n")),
            405);
}

// DNS rebinding: a page of another site whose name resolves to 127.0.0.1 sends that name in Host. It read the status
// (folders, errors) and the page (the WebSocket upgrade alone was checked); every request now names a loopback host
// or is refused.
TEST_F(ConsoleTest, RequestsNamingAnotherHostAreRefusedOnLoopback) {
  const std::string port = std::to_string(console_->port());
  for (const std::string target : {"/", "/api/status", "/console.js"}) {
    const std::string r = Exchange(console_->port(), "GET " + target + " HTTP/1.1\r\nHost: attacker.example:" + port +
                                                         "\r\nConnection: close\r\n\r\n");
    EXPECT_EQ(StatusOf(r), 403) << target;
    EXPECT_NE(BodyOf(r).find("Host names no loopback host"), std::string::npos) << r;
    for (const std::string& host :
         std::vector<std::string>{"127.0.0.1:" + port, "localhost:" + port, "localhost", "[::1]:" + port}) {
      EXPECT_EQ(StatusOf(Exchange(console_->port(),
                                  "GET " + target + " HTTP/1.1\r\nHost: " + host + "\r\nConnection: close\r\n\r\n")),
                200)
          << target << " " << host;
    }
  }
}

// HEAD gets the headers of GET and no body: a body after them was read by a keep-alive client as the start of the
// next answer.
TEST_F(ConsoleTest, HeadGetsTheHeadersWithoutTheBody) {
  const std::string get = Get(console_->port(), "/");
  const std::string head =
      Exchange(console_->port(), "HEAD / HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n");
  EXPECT_EQ(StatusOf(head), 200);
  EXPECT_EQ(BodyOf(head), "");
  ASSERT_FALSE(BodyOf(get).empty());
  EXPECT_NE(head.find("Content-Length: " + std::to_string(BodyOf(get).size()) + "\r\n"), std::string::npos) << head;
}

// A browser page of another site may not open the console's WebSocket (browsers send its Origin and do not apply
// the same-origin rule to WebSockets), nor may a site whose name is rebound to 127.0.0.1; the console's own page
// and programs (no Origin) may.
TEST_F(ConsoleTest, WebSocketsFromOtherOriginsAreRefused) {
  const std::string self = "127.0.0.1:" + std::to_string(console_->port());
  auto handshake = [&](const std::string& host, const std::string& origin) {
    net::io_context ioc;
    websocket::stream<tcp::socket> ws(ioc);
    ws.next_layer().connect(Local(console_->port()));
    ws.set_option(websocket::stream_base::decorator([origin](websocket::request_type& request) {
      if (!origin.empty()) request.set(beast::http::field::origin, origin);
    }));
    beast::error_code ec;
    ws.handshake(host, "/ws", ec);
    if (!ec) return 101;
    // Refused: the server's answer, from the same request sent as is.
    return StatusOf(Exchange(console_->port(), StrCat("GET /ws HTTP/1.1\r\nHost: ", host,
                                                      "\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                                                      "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
                                                      "Sec-WebSocket-Version: 13\r\nOrigin: ",
                                                      origin, "\r\n\r\n")));
  };
  EXPECT_EQ(handshake(self, "http://evil.example"), 403);
  EXPECT_EQ(handshake("evil.example:" + std::to_string(console_->port()),
                      "http://evil.example:" + std::to_string(console_->port())),
            403);  // DNS rebinding: Host and Origin agree, but name no loopback host
  EXPECT_EQ(handshake(self, "null"), 403);
  EXPECT_EQ(handshake(self, "http://" + self), 101);
  EXPECT_EQ(handshake("localhost:" + std::to_string(console_->port()),
                      "http://localhost:" + std::to_string(console_->port())),
            101);
  EXPECT_EQ(handshake(self, ""), 101);
}

TEST_F(ConsoleTest, ControlNeedsTheTokenAndWellFormedCommands) {
  const int port = console_->port();
  const std::string token = TestOptions(dir_).token;
  EXPECT_EQ(StatusOf(Post(port, R"({"cmd":"pause"})", "")), 403);
  EXPECT_EQ(StatusOf(Post(port, R"({"cmd":"pause"})", "0123456789abcdef0123456789abcdee")), 403);
  EXPECT_EQ(StatusOf(Post(port, R"({"cmd":"pause"})", token.substr(0, 31))), 403);
  EXPECT_FALSE(control_.settings().paused);
  EXPECT_EQ(StatusOf(Post(port, "not json", token)), 400);
  EXPECT_EQ(StatusOf(Post(port, R"({"cmd":42})", token)), 400);
  EXPECT_EQ(StatusOf(Post(port, R"({"cmd":"format_disk"})", token)), 400);
  EXPECT_EQ(StatusOf(Post(port, R"({"cmd":"set","stereo_downsample":3})", token)), 400);
  // Integers beyond int must not wrap (4294967298 read as 2), and a budget beyond the smoother's limit would fail
  // every frame after it.
  EXPECT_EQ(StatusOf(Post(port, R"({"cmd":"set","stereo_downsample":4294967298})", token)), 400);
  EXPECT_EQ(StatusOf(Post(port, R"({"cmd":"set","matcher":"spacetime","window_frames":4294967300})", token)), 400);
  EXPECT_EQ(StatusOf(Post(port, R"({"cmd":"set","smooth_budget_ms":1e308})", token)), 400);
  EXPECT_EQ(control_.settings().stereo_downsample, 1);
  EXPECT_EQ(control_.settings().window_frames, 1);
  EXPECT_EQ(StatusOf(Post(port, R"({"cmd":"set","matcher":"magic"})", token)), 400);
  EXPECT_EQ(StatusOf(Post(port, R"({"cmd":"record_start","name":"../escape"})", token)), 400);
  EXPECT_FALSE(std::filesystem::exists(dir_.path() + "/escape"));
  EXPECT_EQ(StatusOf(Post(port, R"({"cmd":"pause"})", token)), 200);
  EXPECT_TRUE(control_.settings().paused);
  EXPECT_EQ(StatusOf(Post(port, R"({"cmd":"set","stereo_downsample":4,"smooth_budget_ms":40})", token)), 200);
  EXPECT_EQ(control_.settings().stereo_downsample, 4);
  EXPECT_EQ(control_.settings().smooth_budget_ms, 40.0);
  EXPECT_EQ(StatusOf(Post(port, R"({"cmd":"set","matcher":"spacetime","window_frames":4})", token)), 200);
  EXPECT_EQ(control_.settings().window_frames, 4);
  EXPECT_EQ(StatusOf(Post(port, R"({"cmd":"record_stop"})", token)), 409);  // not recording
}

// After the run finished, a pause, a capture or a recording was answered "ok" and then nothing happened (a
// recording of no frame that replay refuses); a capture still pending then was never reported.
TEST_F(ConsoleTest, ControlsAfterTheRunFinishedAreRefusedAndAPendingCaptureIsReported) {
  const int port = console_->port();
  const std::string token = TestOptions(dir_).token;
  ASSERT_EQ(StatusOf(Post(port, R"({"cmd":"capture_now"})", token)), 200);
  EXPECT_TRUE(console_->Status()["capture_pending"]);
  EXPECT_EQ(console_->Status()["capture_error"], "");
  console_->Finish();  // the run ended before any frame took the request
  const nlohmann::json j = nlohmann::json::parse(BodyOf(Get(port, "/api/status")));
  EXPECT_FALSE(j["capture_pending"]);
  EXPECT_NE(j["capture_error"].get<std::string>().find("the run ended before"), std::string::npos)
      << j["capture_error"];
  for (const std::string cmd : {R"({"cmd":"pause"})", R"({"cmd":"resume"})", R"({"cmd":"capture_now"})",
                                R"({"cmd":"record_start","name":"late"})", R"({"cmd":"set","stereo_downsample":2})"}) {
    const std::string reply = Post(port, cmd, token);
    EXPECT_EQ(StatusOf(reply), 409) << cmd;
    EXPECT_NE(BodyOf(reply).find("the run has finished"), std::string::npos) << BodyOf(reply);
  }
  EXPECT_FALSE(control_.settings().paused);
  EXPECT_EQ(control_.settings().stereo_downsample, 1);
  EXPECT_FALSE(std::filesystem::exists(dir_.path() + "/recordings/late"));
  EXPECT_EQ(StatusOf(Post(port, R"({"cmd":"pause"})", "")), 403);  // the token is still checked first
}

// A page tells a restarted process (whose token is new) by the status's instance: it differs between two
// consoles and is not the token.
TEST_F(ConsoleTest, StatusNamesTheProcessInstance) {
  const nlohmann::json a = console_->Status();
  ConsoleOptions o = TestOptions(dir_);
  Console other(o, &control_, recording_.rig, RecordingMeta{});
  const nlohmann::json b = other.Status();
  ASSERT_TRUE(a["instance"].is_string());
  EXPECT_FALSE(a["instance"].get<std::string>().empty());
  EXPECT_NE(a["instance"], b["instance"]);
  EXPECT_EQ(o.token.find(a["instance"].get<std::string>()), std::string::npos);
  EXPECT_GT(a["started_unix_ms"].get<std::int64_t>(), 0);
}

// On the live path the frame "capture now" took could be dropped by the queue after capture, and the page waited
// for a capture that never came (PipelineControl.AFullQualityFrameIsNeverDroppedOnTheLivePath tests the queue):
// through the console, a request on a live-path replay gives a capture and clears the pending state.
TEST_F(ConsoleTest, CaptureNowOnTheLivePathArrives) {
  ASSERT_EQ(StatusOf(Post(console_->port(), R"({"cmd":"capture_now"})", TestOptions(dir_).token)), 200);
  PlaybackOptions playback;
  playback.speed = PlaybackSpeed::kRecorded;
  playback.speed_factor = 1000.0;  // frames come far faster than the stages take them: the queue drops
  playback.repeats = 2;
  PlaybackSource source(recording_, playback);
  PipelineOptions options = FastOptions();
  ApplyLivePathPreset(&options);
  options.full_quality_triangulate_downsample = 4;
  options.control = &control_;
  const PipelineSummary s = RunPipeline(source, *recording_.rig, options, {console_.get()});
  EXPECT_GE(s.results, 1);
  EXPECT_EQ(control_.Snapshot().full_quality_done, 1);
  ASSERT_TRUE(WaitFor([&] { return console_->Status()["captures"].size() == 1; }));
  EXPECT_FALSE(console_->Status()["capture_pending"]);
  EXPECT_EQ(console_->Status()["capture_error"], "");
}

// A sink listed before the console whose Finish returns only once the console is writing the capture: its file is a
// FIFO (written through, not replaced) with a one-page buffer that nobody reads yet, so the writer stays in the
// middle of the file until Drain.
class CaptureWriteGate : public PipelineSink {
 public:
  explicit CaptureWriteGate(std::string fifo) : fifo_(std::move(fifo)) {}
  ~CaptureWriteGate() override {
    if (fd_ >= 0) ::close(fd_);
  }
  void Consume(const PipelineResult&) override {}
  void Finish() override {
    fd_ = ::open(fifo_.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd_ < 0) return;
    ::fcntl(fd_, F_SETPIPE_SZ, 4096);
    pollfd p = {fd_, POLLIN, 0};
    writing_ = ::poll(&p, 1, 60000 * RB_TEST_TIMEOUT_FACTOR) == 1;
  }
  bool writing() const { return writing_; }
  // Reads the capture to its end, so that its writer finishes.
  void Drain() {
    if (fd_ < 0) return;
    ::fcntl(fd_, F_SETFL, 0);
    char buffer[65536];
    while (::read(fd_, buffer, sizeof(buffer)) > 0) {
    }
  }

 private:
  std::string fifo_;
  int fd_ = -1;
  bool writing_ = false;
};

// The run ended while the console's thread was writing the capture it had just been given: Finish saw no capture
// waiting and took the request for one that never came, and the page showed "the run ended before a frame was
// taken" beside the capture. (A capture that ends the run, which the full-quality worker makes likely.)
TEST_F(ConsoleTest, ACaptureBeingSavedWhenTheRunEndsIsNotReportedMissing) {
  std::filesystem::create_directories(TestOptions(dir_).capture_dir);
  const std::string fifo = TestOptions(dir_).capture_dir + "/capture_1.ply";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  ASSERT_EQ(StatusOf(Post(console_->port(), R"({"cmd":"capture_now"})", TestOptions(dir_).token)), 200);
  PlaybackSource source(recording_);
  PipelineOptions options = FastOptions();
  options.control = &control_;
  CaptureWriteGate gate(fifo);
  RunPipeline(source, *recording_.rig, options, {&gate, console_.get()});
  ASSERT_TRUE(gate.writing()) << "the console never wrote the capture";
  EXPECT_EQ(console_->Status()["capture_error"], "");
  gate.Drain();
  ASSERT_TRUE(WaitFor([&] { return console_->Status()["captures"].size() == 1; }));
  EXPECT_FALSE(console_->Status()["capture_pending"]);
  EXPECT_EQ(console_->Status()["capture_error"], "");
}

TEST_F(ConsoleTest, OversizedRequestsAreRefused) {
  const int port = console_->port();
  // The body is announced but not sent: the limit is checked against Content-Length first.
  EXPECT_EQ(StatusOf(Exchange(port, "POST /api/control HTTP/1.1\r\nHost: x\r\nContent-Length: 100000\r\n\r\n")), 413);
  EXPECT_EQ(StatusOf(Exchange(port, "GET / HTTP/1.1\r\nHost: x\r\nX-Big: " + std::string(20000, 'a') + "\r\n\r\n")),
            431);
  EXPECT_EQ(StatusOf(Get(port, "/" + std::string(2000, 'a'))), 414);
  EXPECT_EQ(StatusOf(Exchange(port, "THIS IS NOT HTTP\r\n\r\n")), 400);
}

// A WebSocket client that sends one message and reports how the server closed the connection.
websocket::close_code SendAndReadClose(int port, const std::string& message, bool text) {
  net::io_context ioc;
  websocket::stream<tcp::socket> ws(ioc);
  ws.next_layer().connect(Local(port));
  ws.handshake("127.0.0.1", "/ws");
  ws.text(text);
  beast::error_code ec;
  ws.write(net::buffer(message), ec);
  if (ec) return websocket::close_code::none;  // the server closed while the client still wrote
  beast::flat_buffer buffer;
  for (int i = 0; i < 1000 && !ec; ++i) {
    ws.read(buffer, ec);  // status messages may come first
    buffer.consume(buffer.size());
  }
  return ec == websocket::error::closed ? static_cast<websocket::close_code>(ws.reason().code)
                                         : websocket::close_code::none;
}

TEST_F(ConsoleTest, OversizedAndMalformedClientMessagesCloseTheConnection) {
  const int port = console_->port();
  // Too big: closed with code 1009, or reset before the client finished writing it.
  const websocket::close_code big = SendAndReadClose(port, std::string(5000, 'x'), true);
  EXPECT_TRUE(big == websocket::close_code::too_big || big == websocket::close_code::none) << big;
  EXPECT_TRUE(WaitFor([&] { return console_->server_stats().refused >= 1; }));
  EXPECT_EQ(SendAndReadClose(port, "not json", true), websocket::close_code::policy_error);
  EXPECT_EQ(SendAndReadClose(port, R"({"subscribe":{"mesh":7}})", true), websocket::close_code::policy_error);
  EXPECT_EQ(SendAndReadClose(port, R"({"cmd":"pause"})", true), websocket::close_code::policy_error);
  EXPECT_EQ(SendAndReadClose(port, "\x01\x02", false), websocket::close_code::policy_error);
  EXPECT_GE(console_->server_stats().refused, 5);
  EXPECT_FALSE(control_.settings().paused);  // no control over the WebSocket
}

// A client may name at most 16 subscription groups: new names sent in a loop made the server remember each one
// (a page could grow the process without bound); the message that would pass the bound closes the connection.
TEST_F(ConsoleTest, SubscriptionGroupsPerClientAreBounded) {
  net::io_context ioc;
  websocket::stream<tcp::socket> ws(ioc);
  ws.next_layer().connect(Local(console_->port()));
  ws.handshake("127.0.0.1", "/ws");
  auto groups = [](int first) {
    nlohmann::json j;
    for (int g = first; g < first + 8; ++g) j["subscribe"][StrCat("g", g)] = "x";
    return j.dump();
  };
  // The default subscription (mesh) and 8 + 7 new groups: 16, accepted; the same names again change nothing.
  ws.write(net::buffer(groups(0)));
  nlohmann::json seven;
  for (int g = 8; g < 15; ++g) seven["subscribe"][StrCat("g", g)] = "y";
  ws.write(net::buffer(seven.dump()));
  ws.write(net::buffer(groups(0)));
  const int refused_before = console_->server_stats().refused;
  ws.write(net::buffer(R"({"subscribe":{"one-too-many":"x"}})"));
  beast::flat_buffer buffer;
  beast::error_code ec;
  for (int i = 0; i < 1000 && !ec; ++i) {
    ws.read(buffer, ec);
    buffer.consume(buffer.size());
  }
  ASSERT_EQ(ec, websocket::error::closed);
  EXPECT_EQ(static_cast<websocket::close_code>(ws.reason().code), websocket::close_code::policy_error);
  EXPECT_EQ(console_->server_stats().refused, refused_before + 1);
}

// A client that completes the handshake and then never reads, with the smallest socket buffers.
struct StalledClient {
  net::io_context ioc;
  websocket::stream<tcp::socket> ws{ioc};
  explicit StalledClient(int port) {
    ws.next_layer().open(tcp::v4());
    ws.next_layer().set_option(net::socket_base::receive_buffer_size(1024));
    ws.next_layer().connect(Local(port));
    ws.handshake("127.0.0.1", "/ws");
  }
};

TEST(ConsoleServer, AClientThatNeverReadsLosesItsOldestMessagesOnly) {
  ConsoleServerOptions o;
  o.send_buffer_bytes = 4096;
  ConsoleServer server(o, [](const HttpRequest&) { return HttpReply{404, "text/plain", "", {}}; });
  StalledClient stalled(server.port());
  net::io_context ioc;
  websocket::stream<tcp::socket> reader(ioc);
  reader.next_layer().connect(Local(server.port()));
  reader.handshake("127.0.0.1", "/ws");
  ASSERT_TRUE(WaitFor([&] { return server.stats().clients == 2; }));
  constexpr int kMessages = 200;
  for (int i = 0; i < kMessages; ++i) {
    std::string m(64 * 1024, 'm');
    const std::string seq = std::to_string(i);
    m.replace(0, seq.size() + 1, seq + ":");
    server.Broadcast(std::make_shared<const std::string>(std::move(m)), true, "image/left");
  }
  // The newest message always survives: the reading client gets it.
  int last = -1;
  beast::flat_buffer buffer;
  while (last != kMessages - 1) {
    reader.read(buffer);
    const std::string m = beast::buffers_to_string(buffer.data());
    buffer.consume(buffer.size());
    last = std::stoi(m.substr(0, m.find(':')));
  }
  const ConsoleServerStats s = server.stats();
  // The stalled client can hold the 2 queued, 1 in flight and what fits its socket buffers (a few KB):
  // all the rest of its 200 are dropped.
  EXPECT_GE(s.messages_dropped, kMessages - 10);
  EXPECT_EQ(s.clients, 2);
}

// A flood of idle connections: beyond max_connections the oldest idle one is closed for each new one, so the server
// holds no more than the bound and a new request is still answered at once.
TEST(ConsoleServer, IdleConnectionsBeyondTheBoundAreClosedOldestFirst) {
  ConsoleServerOptions o;
  o.max_connections = 4;
  ConsoleServer server(o, [](const HttpRequest&) { return HttpReply{200, "text/plain", "ok", {}}; });
  net::io_context ioc;
  std::vector<tcp::socket> idle;
  for (int i = 0; i < 10; ++i) {
    idle.emplace_back(ioc);
    idle.back().connect(Local(server.port()));
  }
  ASSERT_TRUE(WaitFor([&] { return server.stats().idle_closed == 6; })) << server.stats().idle_closed;
  for (int i = 0; i < 6; ++i) {
    char c = 0;
    beast::error_code ec;
    idle[i].read_some(net::buffer(&c, 1), ec);  // closed by the server: end of stream at once
    EXPECT_TRUE(ec == net::error::eof || ec == net::error::connection_reset) << i << ": " << ec.message();
  }
  const std::string reply = Get(server.port(), "/anything");
  EXPECT_EQ(StatusOf(reply), 200) << reply;
  EXPECT_EQ(server.stats().idle_closed, 7);  // the new one took the place of the oldest of the last four
}

// A message "<n>:" padded to a few KB, and the n of one read back.
std::shared_ptr<const std::string> Numbered(int n) {
  std::string m(4096, 'm');
  const std::string seq = std::to_string(n) + ":";
  m.replace(0, seq.size(), seq);
  return std::make_shared<const std::string>(std::move(m));
}
int ReadNumber(websocket::stream<tcp::socket>& ws) {
  beast::flat_buffer buffer;
  ws.read(buffer);
  const std::string m = beast::buffers_to_string(buffer.data());
  return std::stoi(m.substr(0, m.find(':')));
}

TEST(ConsoleServer, ACreditFlowClientGetsOneMessageThenTheNewestAfterItsAck) {
  ConsoleServer server({}, [](const HttpRequest&) { return HttpReply{404, "text/plain", "", {}}; });
  net::io_context ioc;
  websocket::stream<tcp::socket> client(ioc);
  client.next_layer().connect(Local(server.port()));
  client.handshake("127.0.0.1", "/ws");
  client.text(true);
  client.write(net::buffer(std::string(R"({"flow": "credit"})")));
  ASSERT_TRUE(WaitFor([&] { return server.stats().clients == 1; }));
  // Until the server has read the flow message, every message goes out; then the first one takes the credit.
  int n = 0;
  for (; n < 100; ++n) {
    server.Broadcast(Numbered(n), true, "image/left");
    ASSERT_EQ(ReadNumber(client), n);
    if (!server.Wants("image/left")) break;
  }
  ASSERT_LT(n, 100) << "the server never paced the client";
  EXPECT_TRUE(server.Wants("image/depth"));  // credits are per topic
  for (int k = 1; k <= 3; ++k) server.Broadcast(Numbered(n + k), true, "image/left");
  ASSERT_TRUE(WaitFor([&] { return server.stats().messages_coalesced == 2; }));
  client.write(net::buffer(std::string(R"({"ack": "image/left"})")));
  EXPECT_EQ(ReadNumber(client), n + 3);  // the newest, the two before it replaced while held
  EXPECT_FALSE(server.Wants("image/left"));
  client.write(net::buffer(std::string(R"({"ack": ["image/left", "image/left"]})")));  // one extra: ignored
  EXPECT_TRUE(WaitFor([&] { return server.Wants("image/left"); }));
  server.Broadcast(Numbered(n + 4), true, "image/left");
  EXPECT_EQ(ReadNumber(client), n + 4);
  EXPECT_FALSE(server.Wants("image/left"));
  EXPECT_EQ(server.stats().messages_dropped, 0);
  // A client without credit flow takes every message, whatever the paced one holds.
  websocket::stream<tcp::socket> plain(ioc);
  plain.next_layer().connect(Local(server.port()));
  plain.handshake("127.0.0.1", "/ws");
  ASSERT_TRUE(WaitFor([&] { return server.stats().clients == 2; }));
  EXPECT_TRUE(WaitFor([&] { return server.Wants("image/left"); }));
}

TEST_F(ConsoleTest, AStalledClientDoesNotHoldThePipeline) {
  // Shrunk server socket buffers so that the stalled client fills up within a few frames.
  ConsoleOptions o = TestOptions(dir_);
  o.server.send_buffer_bytes = 4096;
  console_.reset();
  console_ = std::make_unique<Console>(o, &control_, recording_.rig, RecordingMeta{});
  StalledClient stalled(console_->port());
  ASSERT_TRUE(WaitFor([&] { return console_->server_stats().clients == 1; }));
  const PipelineSummary s = ReplayThroughConsole(3);
  EXPECT_EQ(s.results, 24);  // every frame went through
  EXPECT_EQ(s.failed, 0);
  // Each published result sends four images and meshes of tens of KB: far more than a stalled reader's
  // buffers and its queue of 2 per topic hold, so its drops are counted.
  ASSERT_TRUE(WaitFor([&] { return console_->Status()["console"]["results_published"].get<int>() >= 1; }));
  EXPECT_GT(console_->Status()["console"]["messages_dropped"].get<int>(), 0);
}

// Soak: 20 loopback clients (reading, reading slowly, never reading, disconnecting mid-message and coming
// back) while a replay runs through the console: every frame goes through, the server keeps answering, and
// every connection is let go. The frame rate and memory under the same load are measured by
// bench/bench_console_soak (BENCHMARKS.md), not asserted here.
TEST_F(ConsoleTest, SoakTwentyMisbehavingClientsWhileReplayRuns) {
  ConsoleOptions o = TestOptions(dir_);
  o.server.max_clients = 32;
  console_.reset();
  console_ = std::make_unique<Console>(o, &control_, recording_.rig, RecordingMeta{});
  soak::SoakClients clients(console_->port(), 20);
  ASSERT_TRUE(WaitFor([&] { return console_->server_stats().clients >= 15; }));
  const PipelineSummary s = ReplayThroughConsole(3);
  EXPECT_EQ(s.results, 24);
  EXPECT_EQ(s.failed, 0);
  EXPECT_EQ(StatusOf(Get(console_->port(), "/api/status")), 200);
  clients.Stop();
  EXPECT_GT(clients.messages_read(), 0);
  EXPECT_GT(clients.disconnects(), 0);
  EXPECT_TRUE(WaitFor([&] { return console_->server_stats().clients == 0; }))
      << console_->server_stats().clients << " clients still connected";
}

}  // namespace
}  // namespace rangebayes

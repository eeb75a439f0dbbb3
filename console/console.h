// The rig operator's console: a web page served by the process that runs the pipeline (issue 17). It is a
// pipeline sink (images, depth and σ maps, meshes to the page), a frame observer (recordings started from
// the page) and the HTTP handler of a ConsoleServer (the page's files, GET /api/status, POST /api/control).
//
// Nothing here slows the pipeline: Consume only hands the result to the console's own thread, which encodes
// the newest one (older ones it had no time for are skipped and counted) and queues it for each client
// (server.h: slow clients lose their oldest messages; credit-flow clients such as the page get the newest
// when they acknowledge the last). Only images and meshes that some client takes at once are encoded. Recording writes frames in a thread of its own,
// dropping the oldest waiting frame (counted) when the disk cannot keep up.
//
// Viewing (the page, status, the WebSocket stream, captured meshes) needs no token; POST /api/control needs
// the header "X-Rangebayes-Token: <token>" (compared in constant time), on 127.0.0.1 too. Several clients may
// control at once; the last command wins.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "calibration/stereo_rig.h"
#include "capture/recording.h"
#include "capture/stereo_frame.h"
#include "console/assets.h"
#include "console/protocol.h"
#include "console/server.h"
#include "pipeline/bounded_queue.h"
#include "pipeline/pipeline.h"

namespace rangebayes {

class PipelineControl;

struct ConsoleOptions {
  ConsoleServerOptions server;          // address and port (--ui), limits
  std::string token;                    // empty: MakeConsoleToken()
  std::string record_root = "recordings";  // recordings started from the page: record_root/<name>
  std::string capture_dir = "captures";    // "capture now" meshes: capture_dir/capture_<n>.ply
  std::string three_dir = kDebianThreeDir;
  WireMeshOptions wire_mesh;            // meshes are reduced to about this many faces for the wire
  int jpeg_quality = 80;                // 1–100
  double status_period_s = 0.5;         // > 0: a status message to every client this often
  int record_queue_frames = 16;         // ≥ 1: frames waiting for the recording writer
  void Check() const;
};

class Console : public PipelineSink {
 public:
  // Starts the server (throws Error when it cannot listen or three.js is missing). `control` may be null:
  // the page then shows the run without controls. `rig` and `meta` go into recordings made from the page.
  Console(const ConsoleOptions& options, PipelineControl* control, std::optional<StereoRig> rig,
          RecordingMeta meta);
  ~Console() override;
  Console(const Console&) = delete;
  Console& operator=(const Console&) = delete;

  int port() const { return server_->port(); }
  const std::string& token() const { return token_; }
  std::string url() const;  // http://ADDR:PORT/

  // PipelineSink: never waits for clients or encoding.
  void Consume(const PipelineResult& result) override;
  // Stops a recording in progress and tells the clients that the run ended; the page stays served. Controls
  // that act on the run (pause, resume, capture_now, set, record_start) are refused from then on (409).
  void Finish() override;
  // For PipelineOptions::on_frame: queues the frame for the recording in progress, if any.
  void OnFrame(const StereoFrame& frame);

  // What GET /api/status answers. Besides the run's counters: `instance` and `started_unix_ms` (another value:
  // another process, whose token differs), `capture_pending` and `capture_error` (why the last "capture now"
  // gave no mesh: its frame failed, the run ended first, or its file could not be written).
  nlohmann::json Status() const;
  ConsoleServerStats server_stats() const { return server_->stats(); }
  // The server's request handler (public so that tests can call it without a socket).
  HttpReply Handle(const HttpRequest& request);

 private:
  struct Capture {
    int id = 0;
    std::int64_t frame = 0;
    std::string path;
    int vertices = 0;
    int faces = 0;
  };
  struct Recording;

  HttpReply Control(const HttpRequest& request);
  HttpReply StartRecording(const std::string& name);
  HttpReply StopRecording();
  void Work();
  void Publish(const PipelineResult& result);
  void SaveCapture(const PipelineResult& result);
  void BroadcastStatus();
  nlohmann::json RecordingStatus() const;

  ConsoleOptions options_;
  PipelineControl* control_;
  std::optional<StereoRig> rig_;
  RecordingMeta meta_;
  std::string token_;
  std::map<std::string, ConsoleAsset> assets_;
  std::shared_ptr<const std::string> colorbar_png_;

  mutable std::mutex mutex_;  // guards everything below up to the thread
  std::condition_variable wake_;
  std::shared_ptr<const PipelineResult> latest_;
  std::deque<std::shared_ptr<const PipelineResult>> full_quality_;
  bool stopping_ = false;
  bool finished_ = false;
  std::int64_t results_in_ = 0;
  std::int64_t results_skipped_ = 0;
  std::int64_t published_ = 0;
  std::int64_t latest_frame_ = -1;
  double latency_ms_ = 0.0;
  std::deque<double> result_times_s_;  // for the frame rate over the last seconds
  std::vector<std::string> mesh_kinds_;
  std::vector<Capture> captures_;
  int next_capture_id_ = 1;
  std::string last_capture_error_;
  bool capture_pending_ = false;            // "capture now" accepted, its mesh not saved yet
  std::int64_t capture_failed_before_ = 0;  // PipelineSnapshot::full_quality_failed when it was accepted
  std::int64_t capture_done_before_ = 0;    // PipelineSnapshot::full_quality_done when it was accepted
  std::string instance_;                    // tells a page that the process it talks to was restarted
  std::int64_t started_unix_ms_ = 0;

  mutable std::mutex record_mutex_;
  std::unique_ptr<Recording> recording_;
  nlohmann::json last_recording_;  // the one stopped last

  std::unique_ptr<ConsoleServer> server_;
  std::thread worker_;
};

}  // namespace rangebayes

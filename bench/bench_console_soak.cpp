// The console under misbehaving clients: the bundled recording replayed through the live path into the console
// with no WebSocket client, then with 20 loopback clients (reading, reading slowly, never reading,
// disconnecting mid-message and coming back; tests/console/soak_clients.h), alternating. Prints results/s of
// each run and the process's resident memory before and after. See BENCHMARKS.md "Reliability".
//
//   bench_console_soak [REPEATS=10] [ROUNDS=2]     (from the repository root)
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <memory>
#include <string>

#include "bench/bench_main.h"
#include "capture/playback_source.h"
#include "capture/recording.h"
#include "console/console.h"
#include "pipeline/pipeline.h"
#include "pipeline/pipeline_control.h"
#include "tests/console/soak_clients.h"

namespace rb = rangebayes;

int RunBench(int argc, char** argv) {
  const int repeats = argc > 1 ? std::atoi(argv[1]) : 10;
  const int rounds = argc > 2 ? std::atoi(argv[2]) : 2;
  const rb::Recording recording = rb::OpenRecording("recordings/synth_planes_320x240");
  const std::string dir = (std::filesystem::temp_directory_path() / "rb_console_soak").string();
  std::filesystem::create_directories(dir);
  rb::ConsoleOptions o;
  o.record_root = dir + "/recordings";
  o.capture_dir = dir + "/captures";
  o.server.max_clients = 32;
  rb::PipelineControl control;
  rb::Console console(o, &control, recording.rig, rb::RecordingMeta{});
  std::printf("clients  results  wall_s  results/s  rss_before_MB  rss_after_MB  client_msgs  disconnects\n");
  for (int round = 0; round < rounds; ++round) {
    for (const int clients : {0, 20}) {
      const std::int64_t rss_before = rb::soak::ResidentBytes();
      std::unique_ptr<rb::soak::SoakClients> soak;
      if (clients > 0) soak = std::make_unique<rb::soak::SoakClients>(console.port(), clients);
      rb::PlaybackOptions playback;
      playback.repeats = repeats;
      playback.speed = rb::PlaybackSpeed::kFastest;
      rb::PlaybackSource source(recording, playback);
      rb::PipelineOptions options;
      rb::ApplyLivePathPreset(&options);
      options.control = &control;
      const rb::PipelineSummary s = rb::RunPipeline(source, *recording.rig, options, {&console});
      std::int64_t read = 0, disconnects = 0;
      if (soak) {
        soak->Stop();
        read = soak->messages_read();
        disconnects = soak->disconnects();
      }
      std::printf("%7d  %7lld  %6.2f  %9.2f  %13.1f  %12.1f  %11lld  %11lld\n", clients,
                  static_cast<long long>(s.results), s.wall_s, s.results / s.wall_s, rss_before / 1e6,
                  rb::soak::ResidentBytes() / 1e6, static_cast<long long>(read), static_cast<long long>(disconnects));
    }
  }
  std::filesystem::remove_all(dir);
  return 0;
}

// Bad input (a missing file, a wrong option or value) ends with one error line and exit code 1, not an abort.
int main(int argc, char** argv) { return rangebayes::bench::Main("bench_console_soak", RunBench, argc, argv); }

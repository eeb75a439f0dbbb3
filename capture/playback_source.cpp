#include "capture/playback_source.h"

#include <algorithm>
#include <cmath>
#include <thread>

#include "core/error.h"

namespace rangebayes {

void PlaybackOptions::Check() const {
  RB_CHECK(speed_factor > 0.0 && speed_factor <= 1000.0, "playback speed factor must be in (0, 1000], got ",
           speed_factor);
  RB_CHECK(first_position >= 0, "playback first position must be >= 0, got ", first_position);
  RB_CHECK(count >= -1, "playback count must be >= -1, got ", count);
  RB_CHECK(repeats >= 1 && repeats <= 1'000'000, "playback repeats must be in 1..1000000, got ", repeats);
  RB_CHECK(speed != PlaybackSpeed::kStep || static_cast<bool>(step_gate), "step playback needs a step gate");
  RB_CHECK(std::isfinite(max_gap_s) && max_gap_s > 0.0, "playback max_gap_s must be a finite number > 0, got ",
           max_gap_s);
}

PlaybackSource::PlaybackSource(Recording recording, const PlaybackOptions& options)
    : recording_(std::move(recording)), options_(options) {
  options_.Check();
  const int n = recording_.num_frames();
  // A selection of no frame is an error: a run of zero frames would end as if all had gone well.
  RB_CHECK(n > 0, recording_.folder, ": frames.csv lists no frame");
  RB_CHECK(options_.first_position < n, recording_.folder, ": playback starts at position ", options_.first_position,
           ", past the recording's ", n, " frame(s)");
  RB_CHECK(options_.count != 0, "playback count 0 plays no frame (-1: all)");
  position_ = options_.first_position;
  // In 64 bits: first + count passes INT_MAX for a count meant as "all the rest" (--count 2147483647).
  end_position_ =
      options_.count < 0
          ? n
          : static_cast<int>(std::min<std::int64_t>(n, std::int64_t{position_} + std::int64_t{options_.count}));
}

std::string PlaybackSource::Describe() const {
  return StrCat("recording ", recording_.folder, " (", recording_.num_frames(), " frames)");
}

RecordingMeta PlaybackSource::Meta() const {
  RecordingMeta meta = recording_.meta;
  meta["source"] = Describe();
  // What describes the source recording as a whole, not a recording made from it: its state, its count, and synth's
  // frame count (a console recording of a replayed synth recording said frames: "8" beside frame_count: "133").
  meta.erase("complete");
  meta.erase("error");
  meta.erase("frame_count");
  meta.erase("frames");
  return meta;
}

std::optional<std::int64_t> PlaybackSource::frames_total() const {
  if (options_.loop) return std::nullopt;
  return static_cast<std::int64_t>(std::max(0, end_position_ - options_.first_position)) * options_.repeats;
}

StereoFrame PlaybackSource::FrameAt(int position) const { return LoadRecordingFrame(recording_, position); }

StereoFrame PlaybackSource::FrameWithIndex(std::int64_t index) const {
  const auto it = std::lower_bound(recording_.frames.begin(), recording_.frames.end(), index,
                                   [](const RecordingEntry& e, std::int64_t i) { return e.index < i; });
  RB_CHECK(it != recording_.frames.end() && it->index == index, recording_.folder, ": no frame with index ", index);
  return FrameAt(static_cast<int>(it - recording_.frames.begin()));
}

void PlaybackSource::Seek(int position) {
  RB_CHECK(position >= 0 && position <= recording_.num_frames(), recording_.folder, ": seek position ", position,
           " out of range");
  position_ = position;
  clock_started_ = false;
}

FrameResult PlaybackSource::Next() {
  FrameResult result;
  if (position_ >= end_position_) {
    if (end_position_ <= options_.first_position) return result;
    if (!options_.loop && ++plays_done_ >= options_.repeats) return result;
    // Indices keep increasing across loops so that sinks and recorders never see one twice.
    // The next pass's last index stays within kMaxRecordingIndex; the offset, at most that, and the index checked
    // first cannot overflow the sum.
    const std::int64_t last_index = recording_.frames[static_cast<size_t>(end_position_ - 1)].index;
    RB_CHECK(last_index <= kMaxRecordingIndex && loop_index_offset_ + 2 * last_index + 1 <= kMaxRecordingIndex,
             recording_.folder, ": playing it again would number frames past ", kMaxRecordingIndex,
             " (its last index is ", last_index, "); play it fewer times");
    loop_index_offset_ += last_index + 1;
    Seek(options_.first_position);
  }
  if (options_.speed == PlaybackSpeed::kStep && !options_.step_gate()) return result;
  const int position = position_++;
  const RecordingEntry& entry = recording_.frames[static_cast<size_t>(position)];
  if (options_.speed == PlaybackSpeed::kRecorded) {
    const std::int64_t t_ns = std::max(entry.timestamp_left_ns, entry.timestamp_right_ns);
    if (!clock_started_) {
      clock_started_ = true;
      wall_start_ = std::chrono::steady_clock::now();
      recorded_start_ns_ = t_ns;
      gaps_cut_s_ = 0.0;
      last_offset_s_ = 0.0;
    } else {
      // The difference in double, which two timestamps of opposite sign cannot overflow; a gap beyond max_gap_s
      // after the last frame is cut to it (so no damaged timestamp can overflow the clock either).
      double offset_s =
          (static_cast<double>(t_ns) - static_cast<double>(recorded_start_ns_)) * 1e-9 / options_.speed_factor -
          gaps_cut_s_;
      if (offset_s - last_offset_s_ > options_.max_gap_s) {
        gaps_cut_s_ += offset_s - last_offset_s_ - options_.max_gap_s;
        offset_s = last_offset_s_ + options_.max_gap_s;
        ++stats_.gaps_shortened;
      }
      last_offset_s_ = std::max(last_offset_s_, offset_s);
      if (offset_s > 0) {
        const auto until = wall_start_ + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                             std::chrono::duration<double>(offset_s));
        for (auto now = std::chrono::steady_clock::now(); now < until; now = std::chrono::steady_clock::now()) {
          if (options_.stop != nullptr && options_.stop->load(std::memory_order_relaxed)) return FrameResult{};
          std::this_thread::sleep_until(std::min(until, now + std::chrono::milliseconds(20)));
        }
      }
    }
  }
  try {
    result.frame = FrameAt(position);
    result.frame.index += loop_index_offset_;
    result.status = FrameStatus::kFrame;
    ++stats_.frames_delivered;
  } catch (const Error& e) {
    result.status = FrameStatus::kSkipped;
    result.frame.index = entry.index;
    result.reason = e.what();
    ++stats_.frames_skipped;
  }
  return result;
}

}  // namespace rangebayes

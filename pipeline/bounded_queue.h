// A bounded multi-producer multi-consumer queue between pipeline stages. Replay blocks the producer when
// the queue is full (no frame is ever dropped); live drops the oldest waiting item and counts it, so that a
// slow stage always works on the newest frame. Items the queue's `keep` predicate holds (a frame an operator asked
// for) are never dropped: the oldest other item goes instead, or the new one when every waiting item is kept.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <optional>
#include <utility>

namespace rangebayes {

enum class QueueFullPolicy { kBlock, kDropOldest };

template <typename T>
class BoundedQueue {
 public:
  // capacity ≥ 1. `keep` (may be empty: none kept) says which items kDropOldest must not drop.
  BoundedQueue(size_t capacity, QueueFullPolicy policy, std::function<bool(const T&)> keep = nullptr)
      : capacity_(capacity < 1 ? 1 : capacity), policy_(policy), keep_(std::move(keep)) {}

  // Adds an item. kBlock: waits for space. kDropOldest: when full, discards the oldest item that is not kept,
  // or else `item` itself when it is not kept (counted either way); kept items may exceed the capacity. Returns
  // false (and drops `item`) when the queue is closed.
  bool Push(T item) {
    std::unique_lock<std::mutex> lock(mutex_);
    if (policy_ == QueueFullPolicy::kBlock) {
      not_full_.wait(lock, [&] { return closed_ || items_.size() < capacity_; });
    }
    if (closed_) return false;
    if (items_.size() >= capacity_) {
      auto victim = items_.begin();
      while (keep_ && victim != items_.end() && keep_(*victim)) ++victim;
      if (victim == items_.end() && !keep_(item)) {
        ++dropped_;
        return true;
      }
      if (victim != items_.end()) {
        items_.erase(victim);
        ++dropped_;
      }
    }
    items_.push_back(std::move(item));
    lock.unlock();
    not_empty_.notify_one();
    return true;
  }

  // Waits for an item; empty optional once the queue is closed and drained.
  std::optional<T> Pop() {
    std::unique_lock<std::mutex> lock(mutex_);
    not_empty_.wait(lock, [&] { return closed_ || !items_.empty(); });
    if (items_.empty()) return std::nullopt;
    T item = std::move(items_.front());
    items_.pop_front();
    lock.unlock();
    not_full_.notify_one();
    return item;
  }

  // No more pushes; consumers drain what is left, then Pop returns empty.
  void Close() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      closed_ = true;
    }
    not_empty_.notify_all();
    not_full_.notify_all();
  }

  std::int64_t dropped() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return dropped_;
  }
  size_t size() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return items_.size();
  }

 private:
  const size_t capacity_;
  const QueueFullPolicy policy_;
  const std::function<bool(const T&)> keep_;
  mutable std::mutex mutex_;
  std::condition_variable not_empty_;
  std::condition_variable not_full_;
  std::deque<T> items_;
  bool closed_ = false;
  std::int64_t dropped_ = 0;
};

}  // namespace rangebayes

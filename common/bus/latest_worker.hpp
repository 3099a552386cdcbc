#pragma once
// A one-slot mailbox with a worker thread: post() replaces a pending item
// (counted as dropped) so a slow consumer always works on the newest input and
// never queues without bound. In lock-step mode post() runs the work inline,
// so replay is deterministic and nothing is dropped.

#include <condition_variable>
#include <functional>
#include <mutex>
#include <optional>
#include <thread>

#include "bus/stage.hpp"

namespace vslam::bus {

template <class T>
class LatestWinsWorker {
 public:
  LatestWinsWorker(ExecutionMode mode, std::function<void(T&)> work)
      : mode_(mode), work_(std::move(work)) {
    if (mode_ == ExecutionMode::kLive) thread_ = std::thread([this] { loop(); });
  }
  ~LatestWinsWorker() { stop(); }
  LatestWinsWorker(const LatestWinsWorker&) = delete;
  LatestWinsWorker& operator=(const LatestWinsWorker&) = delete;

  // Returns false if a pending item was replaced (a drop).
  bool post(T item) {
    if (mode_ == ExecutionMode::kLockstep) {
      work_(item);
      return true;
    }
    bool replaced = false;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      replaced = pending_.has_value();
      if (replaced) ++dropped_;
      pending_ = std::move(item);
    }
    cv_.notify_all();
    return !replaced;
  }

  // Waits until the mailbox is empty and the worker idle.
  void drain() {
    std::unique_lock<std::mutex> lock(mutex_);
    cv_.wait(lock, [this] { return (!pending_ && !busy_) || stopping_; });
  }

  void stop() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (stopping_) return;
      stopping_ = true;
    }
    cv_.notify_all();
    if (thread_.joinable()) thread_.join();
  }

  int64_t dropped() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return dropped_;
  }

 private:
  void loop() {
    std::unique_lock<std::mutex> lock(mutex_);
    for (;;) {
      cv_.wait(lock, [this] { return pending_.has_value() || stopping_; });
      if (stopping_) return;
      T item = std::move(*pending_);
      pending_.reset();
      busy_ = true;
      lock.unlock();
      work_(item);
      lock.lock();
      busy_ = false;
      cv_.notify_all();
    }
  }

  const ExecutionMode mode_;
  std::function<void(T&)> work_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::optional<T> pending_;
  bool busy_ = false;
  bool stopping_ = false;
  int64_t dropped_ = 0;
  std::thread thread_;
};

}  // namespace vslam::bus

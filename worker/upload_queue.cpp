#include "worker/upload_queue.h"

namespace tessera::worker {

UploadQueue::UploadQueue() : thread_([this] { loop(); }) {}

UploadQueue::~UploadQueue() {
  {
    std::unique_lock lock(mutex_);
    cv_.wait(lock, [&] { return !task_; });
    stopping_ = true;
  }
  cv_.notify_all();
  thread_.join();
}

void UploadQueue::post(std::function<void()> task) {
  {
    std::unique_lock lock(mutex_);
    cv_.wait(lock, [&] { return !task_; });
    task_ = std::move(task);
  }
  cv_.notify_all();
}

void UploadQueue::wait_idle() {
  std::unique_lock lock(mutex_);
  cv_.wait(lock, [&] { return !task_; });
}

void UploadQueue::loop() {
  std::unique_lock lock(mutex_);
  while (true) {
    cv_.wait(lock, [&] { return stopping_ || task_; });
    if (!task_) return;  // stopping with nothing in flight
    std::function<void()> task = task_;
    lock.unlock();
    task();
    task = nullptr;  // the tile's pixels go before the slot frees
    lock.lock();
    task_ = nullptr;
    cv_.notify_all();
  }
}

}  // namespace tessera::worker

#include "cli/private_coordinator.h"

#include <spdlog/spdlog.h>

#include <signal.h>

#include <utility>

namespace tessera::cli {

PrivateCoordinator::PrivateCoordinator(server::CoordinatorOptions options)
    : thread_([this, o = std::move(options)]() mutable { serve(std::move(o)); }) {}

PrivateCoordinator::~PrivateCoordinator() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
    if (running_) running_->stop();
  }
  thread_.join();
}

std::string PrivateCoordinator::error() const {
  std::lock_guard lock(mutex_);
  return error_;
}

void PrivateCoordinator::serve(server::CoordinatorOptions options) {
  // Every thread the coordinator starts inherits this mask: Ctrl-C reaches the command's thread, which stops the farm.
  sigset_t block;
  sigemptyset(&block);
  sigaddset(&block, SIGINT);
  sigaddset(&block, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &block, nullptr);
  try {
    server::Coordinator coordinator(std::move(options));
    const auto publish = [&](server::Coordinator* c) {
      std::lock_guard lock(mutex_);
      running_ = c;
      if (c && stopping_) c->stop();  // asked before it ran: run() takes the stop at once
    };
    publish(&coordinator);
    try {
      coordinator.run();
    } catch (...) {
      publish(nullptr);  // before the coordinator is destroyed
      throw;
    }
    publish(nullptr);
  } catch (const std::exception& e) {
    spdlog::error("coordinator: {}", e.what());
    std::lock_guard lock(mutex_);
    error_ = e.what();
  }
  ended_.store(true);
}

}  // namespace tessera::cli

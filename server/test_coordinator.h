// Test helper: a real coordinator on 127.0.0.1:0 with a fresh data folder, served on a background thread for the
// lifetime of the object (server tests only).
#pragma once

#include "server/coordinator.h"
#include "server/storage.h"

#include <filesystem>
#include <memory>
#include <string>
#include <thread>

namespace tessera::server::testing {

/// Starts a coordinator with the given options (port and data folder are set here) and stops it, joins its thread
/// and removes its data folder on destruction.
class RunningCoordinator {
 public:
  /// Serves `o` on 127.0.0.1:0 with a new folder named tessera-LABEL-test-* under the system temporary folder.
  RunningCoordinator(CoordinatorOptions o, const std::string& label)
      : dir_(std::filesystem::temp_directory_path() / ("tessera-" + label + "-test-" + random_hex(6))) {
    o.port = 0;
    o.data_dir = dir_;
    coord_ = std::make_unique<Coordinator>(o);
    thread_ = std::thread([this] { coord_->run(); });
  }
  ~RunningCoordinator() {
    coord_->stop();
    thread_.join();
    coord_.reset();
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  RunningCoordinator(const RunningCoordinator&) = delete;
  RunningCoordinator& operator=(const RunningCoordinator&) = delete;

  /// The bound address (the port the system picked).
  boost::asio::ip::tcp::endpoint endpoint() const { return coord_->endpoint(); }
  /// The coordinator's data folder.
  const std::filesystem::path& data_dir() const { return dir_; }

 private:
  std::filesystem::path dir_;
  std::unique_ptr<Coordinator> coord_;
  std::thread thread_;
};

}  // namespace tessera::server::testing

// A lease asked for while the worker's previous tile rendered, and the render of its tile when that was begun ahead.
#pragma once

#include "core/render/render.h"
#include "core/scene/scene_loader.h"
#include "protocol/messages.h"
#include "worker/render_signals.h"

#include <tbb/task_group.h>

#include <chrono>
#include <condition_variable>
#include <exception>
#include <memory>
#include <mutex>
#include <optional>

namespace tessera::worker {

/// A job's built scene and the sampling settings of its spec, cached per job id.
struct PreparedJob {
  LoadedScene loaded;                   ///< Scene and BVH.
  protocol::SamplingSettings sampling;  ///< The spec's sampling settings.
};

/// The render of a tile begun before the tile that asked for its lease has finished, on the same task arena: the
/// threads that run out of the current tile's thread tiles take this one's, so no core idles at a tile's end or
/// between tiles (pixels do not depend on which thread renders what).
struct HeadStart {
  RenderSignals signals;
  std::shared_ptr<const PreparedJob> scene;
  tbb::task_group group;               ///< The render task (waited for before this goes).
  std::optional<RenderResult> result;
  std::exception_ptr error;            ///< What the render threw.
  bool enqueued = false;               ///< Its task is in the arena (to be waited for).
  std::mutex mutex;                    ///< With cv: `submitted` turns true once the render task is in `group`.
  std::condition_variable cv;
  bool submitted = false;
};

/// The next lease, asked for while the current tile rendered, with the time of its grant or last heartbeat, and its
/// render when it was begun already.
struct PrefetchedLease {
  protocol::Lease lease;
  std::chrono::steady_clock::time_point beaten;
  std::shared_ptr<HeadStart> head;
  std::optional<protocol::JobSpec> spec;  ///< The job's spec when it came with the lease.

  /// The lease of an answer just received (its grant counts as now), its render not begun.
  static PrefetchedLease granted(protocol::LeaseAnswer answer) {
    return {std::move(answer.lease), std::chrono::steady_clock::now(), nullptr, std::move(answer.spec)};
  }
};

}  // namespace tessera::worker

#include "worker/tile_upload.h"

#include "client/backoff.h"
#include "core/image/image.h"
#include "failpoint/failpoint.h"
#include "protocol/routes.h"
#include "protocol/tile_log.h"

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <limits>

namespace tessera::worker {

using namespace std::chrono_literals;

namespace {

// Removes the first optional header the upload still has, in the order they are given up when the coordinator's header
// limit is too low (its log lines, then the next lease's request), and says what the upload goes without; nullptr
// when none is left.
const char* drop_optional_header(client::HttpRequest& req) {
  static constexpr std::pair<const char*, const char*> kOptional[] = {
      {protocol::kTileLogHeader, "its log lines"}, {protocol::kNextLeaseHeader, "asking for the next lease"}};
  for (const auto& [header, without] : kOptional)
    if (req.headers.erase(header) > 0) return without;
  return nullptr;
}

#if defined(TESSERA_FAILPOINTS)
// The corrupted tile of fail point worker.upload.corrupt: "nan" puts a NaN in the first pixel, "size" drops the last
// column (or row).
std::vector<uint8_t> corrupt_tile(const Image& image, ExrWriteOptions wo, const std::string& how) {
  if (how == "nan") {
    Image bad = image;
    bad.extra.clear();
    bad.rgb[0] = std::numeric_limits<float>::quiet_NaN();
    return encode_exr(bad, wo);
  }
  if (how != "size")
    throw std::runtime_error("fail point worker.upload.corrupt: return(nan) or return(size), not return(" + how + ")");
  const bool narrower = image.width > 1;
  Image bad = Image::make(image.width - (narrower ? 1 : 0), image.height - (narrower ? 0 : 1));
  for (int y = 0; y < bad.height; ++y)
    for (int x = 0; x < bad.width; ++x) bad.set(x, y, image.at(x, y));
  (narrower ? wo.data_window.x1 : wo.data_window.y1) -= 1;
  return encode_exr(bad, wo);
}
#endif

}  // namespace

Delivery upload_tile(client::HttpClient& http, const protocol::Lease& l, const std::string& worker_secret,
                     const std::string& prefix, const RenderResult& res, int width, int height,
                     const std::vector<std::string>& log, const std::optional<protocol::LeaseRequest>& next_lease,
                     std::chrono::milliseconds max_retry_wait, const std::function<std::string()>& give_up) {
  ExrWriteOptions wo;
  wo.compression = ExrCompression::kNone;  // noisy floats barely compress; the CPU is better spent rendering
  wo.data_window = l.window;
  wo.display_window = PixelWindow{0, 0, width, height};
  // A resumable job's tile carries its state channels, a layered job's its output layers.
  wo.write_extra = l.resumable || !res.image.extra.empty();
  std::vector<uint8_t> bytes = encode_exr(res.image, wo);
  TESSERA_FAIL_POINT_RETURN("worker.upload.corrupt", [&](const std::string& how) { bytes = corrupt_tile(res.image, wo, how); });
  client::HttpRequest req;
  req.method = "PUT";
  req.target = protocol::routes::lease_result(l.id);
  req.body.assign(bytes.begin(), bytes.end());
  req.content_type = "image/x-exr";
  req.headers[protocol::kRaysHeader] = std::to_string(res.counters.rays);
  req.headers[protocol::kWorkerSecretHeader] = worker_secret;
  if (std::string header = protocol::tile_log_header(log); !header.empty()) req.headers[protocol::kTileLogHeader] = std::move(header);
  if (next_lease) req.headers[protocol::kNextLeaseHeader] = protocol::next_lease_header(*next_lease);
  TESSERA_FAIL_POINT("worker.upload");
  client::Backoff backoff(200ms, max_retry_wait);
  std::string why;  // the reason to give up, once there is one
  const auto giving_up = [&] {
    if (why.empty() && give_up) why = give_up();
    return !why.empty();
  };
  for (int attempt = 1;; ++attempt) {
    try {
      const client::HttpResponse r = http.send(req, giving_up);
      if (r.status == 200) {
        Delivery settled{DeliveryOutcome::kUploaded, std::nullopt};
        std::string status = "acknowledged";  // an answer without a known status is still an acknowledgement
        try {
          protocol::ResultAnswer answer = protocol::parse_answer<protocol::ResultAnswer>(r.body, "result answer");
          status = protocol::to_string(answer.status);
          settled.next = std::move(answer.next);
        } catch (const protocol::ProtocolError& e) {
          if (next_lease) spdlog::warn("{}: the upload's answer is unreadable, so is its next lease: {}", prefix, e.what());
        }
        spdlog::info("{}: upload {}{}", prefix, status,
                     !next_lease    ? ""
                     : settled.next ? ", next lease " + settled.next->lease.id + " (tile " +
                                          std::to_string(settled.next->lease.tile) + " of job " + settled.next->lease.job + ")"
                                    : ", no next lease");
        bool again = false;  // tests send the result again, as a worker that missed the answer would
        TESSERA_FAIL_POINT_RETURN("worker.upload.repeat", [&](const std::string&) { again = true; });
        if (again) continue;
        return settled;
      }
      if (r.status == 410) {
        spdlog::info("{}: upload discarded (job cancelled or failed)", prefix);
        return {DeliveryOutcome::kDropped, std::nullopt};
      }
      if (r.status == 422) {
        spdlog::error("{}: the coordinator refused the result as invalid: {}", prefix, r.error_text());
        return {DeliveryOutcome::kFailed, std::nullopt};
      }
      if (r.status == 404) {
        spdlog::warn("{}: the coordinator does not know the lease any more; tile dropped", prefix);
        return {DeliveryOutcome::kDropped, std::nullopt};
      }
      // A coordinator whose header limit (serve --max-header-bytes) is below the optional headers' size: the tile goes
      // without its log, then without asking for the next lease (the worker then asks the lease route).
      if (r.status == 431) {
        if (const char* dropped = drop_optional_header(req)) {
          spdlog::warn("{}: upload answered 431: {}; sending it again without {}", prefix, r.error_text(), dropped);
          continue;
        }
      }
      if (!r.retryable()) {
        spdlog::error("{}: upload answered {}: {}; tile dropped", prefix, r.status, r.error_text());
        return {DeliveryOutcome::kDropped, std::nullopt};
      }
      spdlog::warn("{}: upload attempt {} answered {}: {}; retrying", prefix, attempt, r.status, r.error_text());
    } catch (const client::RequestInterrupted&) {
      // the attempt under way was cut short: `why` says why
    } catch (const client::TransportError& e) {
      spdlog::warn("{}: upload attempt {} failed: {}; retrying", prefix, attempt, e.what());
    }
    if (giving_up() || !client::sleep_unless(backoff.next(), giving_up)) {
      spdlog::warn("{}: giving up the upload of tile {} of job {}: {}", prefix, l.tile, l.job, why);
      return {DeliveryOutcome::kDropped, std::nullopt};
    }
  }
}

}  // namespace tessera::worker

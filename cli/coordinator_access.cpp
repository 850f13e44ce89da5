#include "cli/coordinator_access.h"

#include "cli/exit_status.h"
#include "cli/tls_flags.h"
#include "cli/token.h"
#include "client/job_client.h"

#include <spdlog/spdlog.h>

namespace tessera::cli {

std::unique_ptr<client::HttpClient> CoordinatorAccess::client() const {
  auto http = std::make_unique<client::HttpClient>(client::parse_http_url(coordinator), client::HttpTimeouts{},
                                                 uint64_t(2) << 30, tls);
  http->set_bearer_token(load_token(token_file, "TESSERA_CLIENT_TOKEN"));
  return http;
}

int run_with_coordinator(const CoordinatorAccess& access, std::string_view command,
                         const std::function<int(client::HttpClient&)>& body) {
  try {
    const auto client = access.client();
    return body(*client);
  } catch (const client::SubmitError& e) {
    spdlog::error("{}", e.what());
    return kExitRefused;
  } catch (const std::exception& e) {
    spdlog::error("{}: {}", command, e.what());
    return kExitFailed;
  }
}

void add_coordinator_access_flags(CLI::App* command, CoordinatorAccess& access) {
  command->add_option("--coordinator", access.coordinator, "Coordinator URL, e.g. http://127.0.0.1:8470")->required();
  command->add_option("--token-file", access.token_file, "File holding the client token (default: $TESSERA_CLIENT_TOKEN)");
  add_client_tls_flags(command, access.tls);
}

}  // namespace tessera::cli

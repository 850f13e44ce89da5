// The two ways a protocol exchange goes wrong: a message that breaks the protocol, and a request the coordinator
// refuses with an HTTP status.
#pragma once

#include <stdexcept>
#include <string>

namespace tessera::protocol {

/// A message that does not follow the protocol (not JSON, missing or mistyped fields, unknown keys). The coordinator
/// answers such a request with 400 and this text; a client reading such an answer stops with it.
struct ProtocolError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// A request the coordinator refuses: an HTTP status (404, 409, 422, ...) and a sentence saying why.
struct ApiError : std::runtime_error {
  ApiError(int status, const std::string& what) : std::runtime_error(what), status(status) {}
  int status;  ///< HTTP status code.
};

}  // namespace tessera::protocol

#include "server/resource_handler.h"

namespace tessera::server {

void ResourceHandler::handle_async(const protocol::RouteMatch& route, HttpRequest& request, const Caller& caller,
                                   Answer answer) {
  HttpResponse res;
  try {
    res = handle(route, request, caller);
  } catch (...) {
    return answer(HttpResponse{}, std::current_exception());
  }
  answer(std::move(res), nullptr);
}

HttpResponse json_response(http::status status, const nlohmann::json& body, unsigned version) {
  HttpResponse res{status, version};
  res.set(http::field::content_type, "application/json");
  res.body() = body.dump();
  res.prepare_payload();
  return res;
}

HttpResponse bytes_response(std::string bytes, const char* content_type, unsigned version) {
  HttpResponse res{http::status::ok, version};
  res.set(http::field::content_type, content_type);
  res.body() = std::move(bytes);
  res.prepare_payload();
  return res;
}

}  // namespace tessera::server

#include "server/user_file.h"

#include "core/util/file_io.h"
#include "core/util/sha256.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <set>
#include <stdexcept>
#include <system_error>

namespace fs = std::filesystem;
using nlohmann::json;

namespace tessera::server {

std::string user_name_problem(std::string_view name) {
  if (name.empty()) return "a user name must not be empty";
  if (name.size() > 64) return "a user name has at most 64 characters";
  if (name == kClientTokenUser || name == kWorkerTokenUser || name == kOpenUser)
    return "the user name '" + std::string(name) + "' is reserved (it names the caller of the client token, the worker "
           "token or an open coordinator)";
  for (size_t i = 0; i < name.size(); ++i) {
    const char c = name[i];
    const bool alnum = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9');
    if (!alnum && (i == 0 || (c != '.' && c != '_' && c != '-')))
      return "user name '" + std::string(name) +
             "' may contain only letters, digits, '.', '_' and '-', and starts with a letter or digit";
  }
  return "";
}

std::vector<User> read_user_file(const fs::path& file, bool missing_ok) {
  std::error_code ec;
  if (missing_ok && !fs::exists(file, ec)) return {};
  const std::string where = "users file " + file.string();
  json doc;
  try {
    doc = json::parse(read_file_bytes(file));
  } catch (const json::exception& e) {
    throw std::runtime_error(where + ": not JSON: " + e.what());
  }
  if (!doc.is_object() || !doc.contains("users") || !doc["users"].is_array())
    throw std::runtime_error(where + ": expected {\"users\": [...]}");
  std::vector<User> users;
  std::set<std::string> names, tokens;
  for (size_t i = 0; i < doc["users"].size(); ++i) {
    const json& e = doc["users"][i];
    const std::string at = where + ": user " + std::to_string(i + 1);
    if (!e.is_object()) throw std::runtime_error(at + " is not an object");
    for (const auto& [key, value] : e.items())
      if (key != "name" && key != "role" && key != "token_sha256" && key != "weight" && key != "max_workers")
        throw std::runtime_error(at + ": unknown key '" + key + "' (known: name, role, token_sha256, weight, max_workers)");
    User u;
    try {
      u.name = e.at("name").get<std::string>();
      u.role = protocol::role_from_string(e.at("role").get<std::string>());
      u.token_sha256 = e.at("token_sha256").get<std::string>();
      u.weight = e.value("weight", 1.0);
      u.max_workers = e.value("max_workers", int64_t(0));
    } catch (const json::exception& x) {
      throw std::runtime_error(at + ": " + x.what());
    } catch (const std::invalid_argument& x) {
      throw std::runtime_error(at + ": " + x.what());
    }
    if (std::string p = user_name_problem(u.name); !p.empty()) throw std::runtime_error(at + ": " + p);
    if (!is_sha256_hex(u.token_sha256))
      throw std::runtime_error(at + " (" + u.name + "): token_sha256 must be 64 lowercase hex digits");
    if (!(u.weight > 0) || !std::isfinite(u.weight))
      throw std::runtime_error(at + " (" + u.name + "): weight must be a positive number");
    if (u.max_workers < 0) throw std::runtime_error(at + " (" + u.name + "): max_workers must be 0 (no cap) or more");
    if (!names.insert(u.name).second) throw std::runtime_error(at + ": user '" + u.name + "' is listed twice");
    if (!tokens.insert(u.token_sha256).second)
      throw std::runtime_error(at + " (" + u.name + "): its token is another user's too");
    users.push_back(std::move(u));
  }
  return users;
}

void write_user_file(const fs::path& file, const std::vector<User>& users) {
  json list = json::array();
  for (const User& u : users) {
    json e = {{"name", u.name}, {"role", protocol::to_string(u.role)}, {"token_sha256", u.token_sha256}};
    if (u.weight != 1) e["weight"] = u.weight;
    if (u.max_workers) e["max_workers"] = u.max_workers;
    list.push_back(std::move(e));
  }
  try {
    write_file_atomic(file, json{{"users", list}}.dump(2) + "\n");
    fs::permissions(file, fs::perms::owner_read | fs::perms::owner_write);
  } catch (const std::exception& e) {
    throw std::runtime_error("cannot write users file " + file.string() + ": " + e.what());
  }
}

}  // namespace tessera::server

#include "server/auth.h"

#include "core/util/sha256.h"

#include <openssl/crypto.h>
#include <sys/random.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <stdexcept>

namespace tessera::server {

namespace {

// Digests compared in time independent of where they differ.
bool same_digest(const Sha256Digest& a, const Sha256Digest& b) { return CRYPTO_memcmp(a.data(), b.data(), a.size()) == 0; }

}  // namespace

bool constant_time_equal(std::string_view a, std::string_view b) {
  // Hashing first makes the comparison independent of the lengths; CRYPTO_memcmp does not stop at the first difference.
  return same_digest(sha256_digest(a), sha256_digest(b));
}

std::string generate_token() {
  unsigned char bytes[24];
  // The kernel's generator, as OpenSSL's own seeds from: asking it directly spares a process that makes a token
  // first thing (`render --workers`, before starting its coordinator) OpenSSL's start-up, about 1.5 ms.
  for (size_t got = 0; got < sizeof bytes;) {
    const ssize_t n = ::getrandom(bytes + got, sizeof bytes - got, 0);
    if (n > 0) got += size_t(n);
    else if (n < 0 && errno != EINTR) throw std::runtime_error("the system random source failed; cannot make a token");
  }
  static const char* digits = "0123456789abcdef";
  std::string out;
  for (unsigned char b : bytes) {
    out += digits[b >> 4];
    out += digits[b & 15];
  }
  return out;
}

std::string token_problem(std::string_view token) {
  if (token.size() < 16) return "a token must have at least 16 characters (it has " + std::to_string(token.size()) + ")";
  if (token.size() > 4096) return "a token must have at most 4096 characters";
  for (char c : token)
    if (c <= ' ' || c > '~') return "a token may contain only printable ASCII characters without spaces";
  return "";
}

struct Credentials::Users {
  std::vector<User> list;
  std::map<Sha256Digest, const User*> by_token;
  std::map<std::string, const User*, std::less<>> by_name;
  bool any_worker = false;
};

std::shared_ptr<const Credentials::Users> Credentials::users_snapshot() const {
  std::lock_guard lock(mu_);
  return users_;
}

namespace {

Sha256Digest digest_of_hex(const std::string& hex) {
  Sha256Digest d{};
  for (size_t i = 0; i < d.size(); ++i) d[i] = uint8_t(std::stoi(hex.substr(2 * i, 2), nullptr, 16));
  return d;
}

std::string hex_of(const Sha256Digest& d) {
  static const char* digits = "0123456789abcdef";
  std::string out;
  for (uint8_t b : d) {
    out += digits[b >> 4];
    out += digits[b & 15];
  }
  return out;
}

}  // namespace

Credentials::Credentials(const AccessTokens& tokens) : users_file_(tokens.users_file) {
  if (!tokens.client.empty()) client_ = sha256_digest(tokens.client);
  if (!tokens.worker.empty()) worker_ = sha256_digest(tokens.worker);
  reload();
}

size_t Credentials::reload() {
  std::shared_ptr<const Users> fresh;
  {
    auto u = std::make_shared<Users>();
    if (!users_file_.empty()) u->list = read_user_file(users_file_);
    for (const User& user : u->list) {
      u->by_token[digest_of_hex(user.token_sha256)] = &user;
      u->by_name[user.name] = &user;
      u->any_worker = u->any_worker || user.role == protocol::Role::worker;
    }
    fresh = std::move(u);
  }
  std::lock_guard lock(mu_);
  users_ = fresh;
  return fresh->list.size();
}

std::vector<User> Credentials::users() const { return users_snapshot()->list; }

bool Credentials::client_open() const { return !client_ && users_file_.empty(); }

bool Credentials::complete() const {
  return !client_open() && (worker_ || users_snapshot()->any_worker);
}

AuthDecision Credentials::authorize(Access need, std::string_view authorization, std::string_view cert_subject) const {
  using protocol::Role;
  if (need == Access::open) return {AuthDecision::allowed, "", Caller{}, "open"};
  const std::shared_ptr<const Users> users = users_snapshot();
  const bool client_side = !client_open();
  const bool worker_side = worker_ || users->any_worker;
  // A side with no credential configured is open (the coordinator then listens on loopback only).
  const bool open = need == Access::worker   ? !worker_side
                    : need == Access::either ? !client_side && !worker_side
                                             : !client_side;
  if (open) {
    const Caller c = need == Access::worker ? Caller{std::string(kWorkerTokenUser), Role::worker} : Caller{};
    return {AuthDecision::allowed, "", c, "open"};
  }
  AuthDecision d;
  if (authorization.empty()) {
    // A verified client certificate whose common name is a user's stands for that user.
    const auto it = cert_subject.empty() ? users->by_name.end() : users->by_name.find(cert_subject);
    if (it == users->by_name.end())
      return {AuthDecision::missing,
              "this endpoint needs a credential of " + protocol::roles_admitted(need) + " (Authorization: Bearer " +
                  (need == Access::worker ? "<the worker token or a worker user's token>)"
                                          : "<the client token or a user's token>)"),
              {}, ""};
    d.caller = {it->second->name, it->second->role};
    d.credential = "cert:" + it->second->name;
  } else {
    // The scheme is case-insensitive and followed by one or more spaces (RFC 9110, 11.4).
    constexpr std::string_view kScheme = "bearer";
    const bool scheme_ok = authorization.size() > kScheme.size() + 1 && authorization[kScheme.size()] == ' ' &&
                           std::equal(kScheme.begin(), kScheme.end(), authorization.begin(), [](char a, char b) {
                             return a == char(std::tolower(static_cast<unsigned char>(b)));
                           });
    const size_t token_at = scheme_ok ? authorization.find_first_not_of(' ', kScheme.size()) : std::string_view::npos;
    if (token_at == std::string_view::npos)
      return {AuthDecision::invalid, "the Authorization header must be 'Bearer <token>'", {}, ""};
    // Both token comparisons always run, so the time taken does not say which (if any) matched; a user's token is
    // found by its digest, whose bytes say nothing usable about the token.
    const Sha256Digest digest = sha256_digest(authorization.substr(token_at));
    const bool is_client = client_ && same_digest(digest, *client_);
    const bool is_worker = worker_ && same_digest(digest, *worker_);
    const auto user = users->by_token.find(digest);
    if (is_client) {
      d.caller = {std::string(kClientTokenUser), Role::admin};
      d.credential = "client";
    } else if (is_worker) {
      d.caller = {std::string(kWorkerTokenUser), Role::worker};
      d.credential = "worker";
    } else if (user != users->by_token.end()) {
      d.caller = {user->second->name, user->second->role};
      d.credential = "token:" + hex_of(digest);
    } else {
      return {AuthDecision::invalid, "the bearer token is not valid for this coordinator", {}, ""};
    }
  }
  if (!protocol::role_allows(d.caller.role, need)) {
    d.status = AuthDecision::wrong_role;
    d.reason = "this endpoint needs " + protocol::roles_admitted(need) + "; " + d.caller.user + " has the " +
               protocol::to_string(d.caller.role) + " role";
  }
  return d;
}

bool Credentials::admits(const std::string& credential, Access need) const {
  using protocol::Role;
  if (credential == "open") return true;
  if (credential == "client") return client_.has_value() && protocol::role_allows(Role::admin, need);
  if (credential == "worker") return worker_.has_value() && protocol::role_allows(Role::worker, need);
  const std::shared_ptr<const Users> users = users_snapshot();
  const User* u = nullptr;
  if (credential.rfind("token:", 0) == 0 && credential.size() == 6 + 64) {
    const auto it = users->by_token.find(digest_of_hex(credential.substr(6)));
    if (it != users->by_token.end()) u = it->second;
  } else if (credential.rfind("cert:", 0) == 0) {
    const auto it = users->by_name.find(std::string_view(credential).substr(5));
    if (it != users->by_name.end()) u = it->second;
  }
  return u && protocol::role_allows(u->role, need);
}

AuthDecision authorize(Access need, std::string_view authorization, const AccessTokens& tokens) {
  return Credentials(tokens).authorize(need, authorization);
}

}  // namespace tessera::server

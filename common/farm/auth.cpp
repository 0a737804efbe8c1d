#include "common/farm/auth.h"

#include <openssl/crypto.h>
#include <openssl/sha.h>
#include <spdlog/spdlog.h>
#include <sys/stat.h>

#include <cstdlib>
#include <fstream>

namespace locus::farm {
namespace {

constexpr std::string_view kBearer = "Bearer ";
// Longer tokens are refused unread: no reason to hash megabytes.
constexpr size_t kMaxTokenBytes = 4096;

std::string_view trim(std::string_view s) {
  const auto space = [](char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; };
  while (!s.empty() && space(s.front())) s.remove_prefix(1);
  while (!s.empty() && space(s.back())) s.remove_suffix(1);
  return s;
}

// A header value carries visible ASCII only; so must a token.
bool printable(std::string_view s) {
  for (unsigned char c : s)
    if (c < 0x21 || c > 0x7e) return false;
  return true;
}

// A client or admin line: "NAME TOKEN", or a token alone named
// `prefix`-LINE. Returns {name, token}.
std::pair<std::string, std::string> named_line(std::string_view line, int number,
                                               const char* prefix) {
  const size_t space = line.find_first_of(" \t");
  if (space == std::string_view::npos) {
    return {std::string(prefix) + "-" + std::to_string(number), std::string(line)};
  }
  return {std::string(line.substr(0, space)), std::string(trim(line.substr(space + 1)))};
}

// The lines of a token file, trimmed, line k at index k - 1; # comments and
// blank lines are kept as empty strings (the numbering names unnamed
// users). Each line is a token, or with `named` "NAME TOKEN" or a token.
// `flag` names the file in messages ("--client-tokens").
Result<std::vector<std::string>> read_token_lines(const std::string& path, const std::string& flag,
                                                  bool named) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return FailedPrecondition(flag + " " + path + ": cannot read the file");
  std::vector<std::string> lines;
  bool any = false;
  std::string line;
  while (std::getline(in, line)) {
    const std::string_view t = trim(line);
    if (t.empty() || t.front() == '#') {
      lines.emplace_back();
      continue;
    }
    const int number = static_cast<int>(lines.size()) + 1;
    const auto [name, token] =
        named ? named_line(t, number, "token") : std::pair{std::string("-"), std::string(t)};
    if (!printable(name) || name.size() > 64 || !printable(token) ||
        token.size() > kMaxTokenBytes) {
      return InvalidArgument(flag + " " + path + ":" + std::to_string(number) + ": " +
                             (named ? "expected NAME TOKEN or a token alone (a name of at most 64 "
                                      "and a token of 1.."
                                    : "a token is 1..") +
                             std::to_string(kMaxTokenBytes) +
                             " visible ASCII characters without spaces" + (named ? ")" : ""));
    }
    lines.emplace_back(t);
    any = true;
  }
  if (!any) {
    return InvalidArgument(flag + " " + path + ": holds no token (" +
                           (named ? "NAME TOKEN" : "one") + " per line; # starts a comment)");
  }
  struct stat st {};
  if (stat(path.c_str(), &st) == 0 && (st.st_mode & (S_IRWXG | S_IRWXO)) != 0) {
    spdlog::warn("{} {}: readable by other users; chmod 600 it", flag, path);
  }
  return lines;
}

// The tokens of a file that holds tokens alone.
Result<std::vector<std::string>> read_tokens(const std::string& path, const std::string& flag) {
  auto lines = read_token_lines(path, flag, false);
  if (!lines.ok()) return lines.status();
  std::vector<std::string> tokens;
  for (std::string& l : *lines) {
    if (!l.empty()) tokens.push_back(std::move(l));
  }
  return tokens;
}

}  // namespace

Result<std::string> load_token(const std::string& token_file) {
  if (!token_file.empty()) {
    auto tokens = read_tokens(token_file, "--token-file");
    if (!tokens.ok()) return tokens.status();
    return tokens->front();
  }
  const char* env = std::getenv("LOCUS_TOKEN");
  if (env == nullptr) return std::string();
  const std::string_view t = trim(env);
  if (!printable(t) || t.size() > kMaxTokenBytes) {
    return InvalidArgument("LOCUS_TOKEN: a token is 1.." + std::to_string(kMaxTokenBytes) +
                           " visible ASCII characters without spaces");
  }
  return std::string(t);
}

Result<std::string> random_token() {
  std::ifstream in("/dev/urandom", std::ios::binary);
  unsigned char bytes[32];
  if (!in.read(reinterpret_cast<char*>(bytes), sizeof bytes))
    return Internal("cannot read /dev/urandom for a token");
  static const char* kHex = "0123456789abcdef";
  std::string token;
  for (unsigned char b : bytes) {
    token += kHex[b >> 4];
    token += kHex[b & 15];
  }
  return token;
}

Result<Authenticator> Authenticator::from_files(const std::string& client_tokens,
                                                const std::string& worker_tokens,
                                                const std::string& admin_tokens) {
  auto clients = read_token_lines(client_tokens, "--client-tokens", true);
  if (!clients.ok()) return clients.status();
  auto workers = read_tokens(worker_tokens, "--worker-tokens");
  if (!workers.ok()) return workers.status();
  std::vector<std::string> admins;
  if (!admin_tokens.empty()) {
    auto a = read_token_lines(admin_tokens, "--admin-tokens", true);
    if (!a.ok()) return a.status();
    admins = std::move(*a);
  }
  return from_tokens(*clients, *workers, admins);
}

Authenticator Authenticator::from_tokens(const std::vector<std::string>& client_lines,
                                         const std::vector<std::string>& worker_tokens,
                                         const std::vector<std::string>& admin_lines) {
  Authenticator a;
  a.enforcing_ = true;
  for (size_t i = 0; i < client_lines.size(); ++i) {
    if (client_lines[i].empty()) continue;
    const auto [name, token] = named_line(client_lines[i], static_cast<int>(i) + 1, "token");
    a.add(token, Role::kClient, name);
  }
  for (const std::string& t : worker_tokens) a.add(t, Role::kWorker);
  for (size_t i = 0; i < admin_lines.size(); ++i) {
    if (admin_lines[i].empty()) continue;
    const auto [name, token] = named_line(admin_lines[i], static_cast<int>(i) + 1, "admin");
    a.add(token, Role::kClient, name, true);
  }
  return a;
}

void Authenticator::add(std::string_view token, Role role, const std::string& user, bool admin) {
  Entry e;
  SHA256(reinterpret_cast<const unsigned char*>(token.data()), token.size(), e.digest.data());
  Entry* have = nullptr;
  for (Entry& t : tokens_) {
    if (t.digest == e.digest) have = &t;
  }
  if (!have) {
    tokens_.push_back(e);
    have = &tokens_.back();
  }
  (role == Role::kClient ? have->client : have->worker) = true;
  // An admin line names the user over a client line of the same token.
  if (role == Role::kClient && (admin || have->user.empty())) have->user = user;
  have->admin |= admin;
}

Status Authenticator::check(Role needed, std::string_view authorization,
                            bool peer_certificate_verified, std::string_view method) const {
  return identify(needed, authorization, peer_certificate_verified, method).status();
}

Result<Caller> Authenticator::identify(Role needed, std::string_view authorization,
                                       bool peer_certificate_verified,
                                       std::string_view method) const {
  const std::string call(method);
  if (needed == Role::kWorker && worker_certificate_ && !peer_certificate_verified) {
    return Status(Code::kUnauthenticated,
                  call +
                      ": a worker must present a client certificate signed by the "
                      "coordinator's --tls-ca (locus-worker --tls-cert/--tls-key)");
  }
  if (!enforcing_) return Caller::anyone();
  if (authorization.empty()) {
    return Status(Code::kUnauthenticated,
                  call + ": no bearer token (give --token-file FILE or set LOCUS_TOKEN)");
  }
  if (authorization.size() <= kBearer.size() ||
      authorization.substr(0, kBearer.size()) != kBearer ||
      authorization.size() - kBearer.size() > kMaxTokenBytes) {
    return Status(Code::kUnauthenticated,
                  call + ": the authorization header is not \"Bearer <token>\"");
  }
  const std::string_view token = authorization.substr(kBearer.size());
  // Constant time in the token's contents: the digest of what was sent is
  // compared with every known digest in full, without stopping at a match.
  Digest digest;
  SHA256(reinterpret_cast<const unsigned char*>(token.data()), token.size(), digest.data());
  bool known = false, client = false, worker = false;
  const Entry* match = nullptr;
  for (const Entry& e : tokens_) {
    const bool same = CRYPTO_memcmp(e.digest.data(), digest.data(), digest.size()) == 0;
    known |= same;
    client |= same & e.client;
    worker |= same & e.worker;
    match = same ? &e : match;
  }
  if (!known) return Status(Code::kUnauthenticated, call + ": the token is not valid here");
  if ((needed == Role::kClient && !client) || (needed == Role::kWorker && !worker)) {
    const Role has = client ? Role::kClient : Role::kWorker;
    return Status(Code::kPermissionDenied, call + ": a " + role_name(has) +
                                               " token may not make this call (" +
                                               role_name(needed) + " tokens only)");
  }
  return Caller{match->user, match->admin};
}

}  // namespace locus::farm

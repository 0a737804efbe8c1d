// Who may call what on a coordinator: bearer tokens with roles, checked in
// constant time. A plain class (no gRPC): server/grpc_service.cpp hands it
// the call's `authorization` header and whether the peer showed a verified
// client certificate; tests and the fuzzer call it directly.
// docs/farm.md "Security".
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "common/base/labels.h"
#include "common/base/status.h"

namespace locus::farm {

// ClientService (submit, status, watch, cancel, workers, fetch) is the
// client role's; WorkerService (Register, GetTask, GetScene, CompleteBand,
// Heartbeat) the worker role's.
enum class Role { kClient, kWorker };
inline constexpr Labels<Role, 2> kRoleLabels = {
    {{Role::kClient, "client"}, {Role::kWorker, "worker"}}};
// A C string: every name in the table (and the fallback) is a literal.
inline const char* role_name(Role role) { return label_name(kRoleLabels, role).data(); }

// Who makes a call: the user its client token names (`--client-tokens`
// lines "NAME TOKEN"), and whether it is an admin (`--admin-tokens`). A farm
// without tokens treats every caller as an unnamed admin.
struct Caller {
  std::string user;
  bool admin = false;
  // The coordinator itself, tests, and callers of a farm without tokens.
  static Caller anyone() { return Caller{"", true}; }
};

// What a client or worker needs to reach a coordinator (plain strings, so
// that worker/ and client/ options carry them without gRPC headers).
struct Credentials {
  std::string token;     // sent as "authorization: Bearer <token>"; empty: none
  std::string tls_ca;    // PEM file verifying the coordinator: TLS
  std::string tls_cert;  // PEM files of a client certificate (mutual TLS)
  std::string tls_key;
  bool insecure = false;  // plaintext even to a non-loopback address
};

// The token from `--token-file FILE` when given, else from the LOCUS_TOKEN
// environment variable, else empty (no token). The file's first line that
// is neither empty nor a # comment is the token.
Result<std::string> load_token(const std::string& token_file);

// 32 bytes from /dev/urandom, hex: the embedded farm's token.
Result<std::string> random_token();

class Authenticator {
 public:
  // Open: every call allowed (`--insecure` without token files).
  Authenticator() = default;
  // One token per line; empty lines and # comments skipped, surrounding
  // white space trimmed. A token may be in several files (several roles).
  // Client and admin lines are "NAME TOKEN" or a token alone, whose user is
  // then named after its line ("token-3" in the client file, "admin-3" in
  // the admin file); an admin token is also a client token. Worker lines
  // hold a token only.
  static Result<Authenticator> from_files(const std::string& client_tokens,
                                          const std::string& worker_tokens,
                                          const std::string& admin_tokens = "");
  // The same from lines as the files hold them.
  static Authenticator from_tokens(const std::vector<std::string>& client_lines,
                                   const std::vector<std::string>& worker_tokens,
                                   const std::vector<std::string>& admin_lines = {});

  // Worker calls then also need a client certificate that TLS verified
  // against the coordinator's --tls-ca.
  void require_worker_certificate(bool require) { worker_certificate_ = require; }

  bool enforcing() const { return enforcing_; }

  // Ok, Unauthenticated (missing, malformed or unknown token; a worker
  // without a required certificate) or PermissionDenied (a valid token of
  // the other role). `authorization` is the header's value, absent as "".
  // `method` ("ClientService.SubmitJob") only words the message. The
  // messages never contain the token.
  Status check(Role needed, std::string_view authorization, bool peer_certificate_verified,
               std::string_view method) const;
  // check(), and on success who the caller is.
  Result<Caller> identify(Role needed, std::string_view authorization,
                          bool peer_certificate_verified, std::string_view method) const;

 private:
  using Digest = std::array<uint8_t, 32>;
  struct Entry {
    Digest digest;
    bool client = false;
    bool worker = false;
    bool admin = false;
    std::string user;
  };
  void add(std::string_view token, Role role, const std::string& user = "", bool admin = false);

  bool enforcing_ = false;
  bool worker_certificate_ = false;
  std::vector<Entry> tokens_;
};

}  // namespace locus::farm

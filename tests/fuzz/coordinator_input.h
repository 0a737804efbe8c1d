// The coordinator fuzzer's input format, shared with its seed maker: a
// sequence of requests, each [kind byte][length: 2 bytes, little endian]
// [serialized request message]. The kind's low 4 bits pick the RPC
// (Rpc below); bit 0x80 fills the request's ids (worker, lease, job,
// scene) from earlier answers, since lease ids are random and could not be
// guessed; bit 0x40 gives a CompleteBand pixels of the right size.
#pragma once

#include <cstdint>
#include <string>

namespace locus::fuzz {

enum Rpc : uint8_t {
  kSubmitJob,
  kGetJob,
  kListJobs,
  kWatchJob,
  kCancelJob,
  kListWorkers,
  kFetchResults,
  kRegister,
  kGetTask,
  kGetScene,
  kCompleteBand,
  kHeartbeat,
  kPauseJob,     // also ResumeJob (the kind's kRightSize bit) or RetryJob (odd length)
  kSetPriority,  // also RequeueJob, by the kind's kRightSize bit
  kListEvents,
  kWorkerAction,  // DrainWorker, DisableWorker or EnableWorker, by the request's bytes
  kRpcCount
};
inline constexpr uint8_t kFillIds = 0x80;
inline constexpr uint8_t kRightSize = 0x40;

inline void append_request(std::string& input, uint8_t kind, const std::string& message) {
  input += static_cast<char>(kind);
  const size_t n = message.size() > 0xffff ? 0xffff : message.size();
  input += static_cast<char>(n & 0xff);
  input += static_cast<char>(n >> 8);
  input.append(message, 0, n);
}

}  // namespace locus::fuzz

// A job larger than one gRPC message (client/farm_client.h,
// check_submission_size; docs/farm.md "Limits"): refused before anything is
// sent, naming the scene, its size and what to do, and not confused with a
// scene that fits. `locus render` without --workers renders such a scene in
// process instead (tests/farm_processes.sh).
#include <gtest/gtest.h>

#include "client/farm_client.h"
#include "common/farm/types.h"
#include "proto/scene.pb.h"

namespace locus::client {
namespace {

// A scene of one mesh of `positions` vertices (24 bytes each on the wire).
farm::SubmitRequest request_with_mesh(int positions) {
  farm::SubmitRequest r;
  r.scene_name = "big.nff";
  v1::Mesh* mesh = r.scene.add_objects()->mutable_mesh();
  mesh->mutable_positions()->Resize(3 * positions, 0.5);
  return r;
}

TEST(SubmissionSize, AJobLargerThanOneMessageIsRefusedBeforeItIsSent) {
  const farm::SubmitRequest small = request_with_mesh(1000);
  EXPECT_TRUE(check_submission_size(small).ok());
  // 3.2 M positions: 73 MiB, over the 64 MiB message.
  const farm::SubmitRequest big = request_with_mesh(3200000);
  const Status s = check_submission_size(big);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.code(), Code::kResourceExhausted);
  EXPECT_NE(s.message().find("big.nff: the scene is 73.2 MiB as a farm job (1 objects)"),
            std::string::npos)
      << s.message();
  EXPECT_NE(s.message().find("at most 63 MiB"), std::string::npos) << s.message();
  // Just under the line: accepted (the message's other fields fit beside it).
  EXPECT_TRUE(check_submission_size(request_with_mesh(2700000)).ok());
  // FarmClient::submit refuses it with the fix, before any call: no
  // coordinator listens at this address, and the answer is not
  // "unavailable".
  FarmClient farm("127.0.0.1:1");
  const auto r = farm.submit(big);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Code::kResourceExhausted) << r.status().message();
  EXPECT_NE(r.status().message().find("locus render --workers 0"), std::string::npos)
      << r.status().message();
}

}  // namespace
}  // namespace locus::client

// Health and shutdown: the standard gRPC health service (readiness and
// liveness) on its own port and on the coordinator's, and the SIGTERM
// drain: no new jobs or leases, the bands in flight still accepted and
// recorded, NOT_SERVING meanwhile. The drain's logic is tested without a
// network first, then over 127.0.0.1.
#include "proto/wire/health.h"

#include <gtest/gtest.h>

#include <future>
#include <thread>

#include "tests/farm_fixture.h"

namespace locus::farm {
namespace {

namespace fs = std::filesystem;
using testing_farm::FarmTest;

// SERVING / NOT_SERVING of `service` at `address`, or the error's message.
std::string health_of(const std::string& address, const std::string& service = "") {
  auto r = rpc::check_health(address, service, Credentials(), Millis(3000));
  if (!r.ok()) return r.status().message();
  return *r ? "SERVING" : "NOT_SERVING";
}

TEST(HealthServer, ReadinessLivenessAndUnknownNames) {
  rpc::HealthServer health;
  auto port = health.start("127.0.0.1:0");
  ASSERT_TRUE(port.ok()) << port.status().message();
  const std::string address = "127.0.0.1:" + std::to_string(*port);
  EXPECT_EQ(health_of(address), "NOT_SERVING") << "not ready before set_ready";
  EXPECT_EQ(health_of(address, rpc::kLivenessService), "SERVING");
  health.set_ready(true);
  EXPECT_EQ(health_of(address), "SERVING");
  auto unknown = rpc::check_health(address, "locus.v1.Nope", Credentials(), Millis(3000));
  ASSERT_FALSE(unknown.ok());
  EXPECT_EQ(unknown.status().code(), Code::kNotFound);

  // Watch: the status now, then the change.
  auto channel = grpc::CreateChannel(address, grpc::InsecureChannelCredentials());
  auto stub = grpc::health::v1::Health::NewStub(channel);
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
  grpc::health::v1::HealthCheckRequest req;
  auto reader = stub->Watch(&ctx, req);
  grpc::health::v1::HealthCheckResponse resp;
  ASSERT_TRUE(reader->Read(&resp));
  EXPECT_EQ(resp.status(), grpc::health::v1::HealthCheckResponse::SERVING);
  health.set_ready(false);
  ASSERT_TRUE(reader->Read(&resp));
  EXPECT_EQ(resp.status(), grpc::health::v1::HealthCheckResponse::NOT_SERVING);
  // Shutting down ends the watch with a last NOT_SERVING.
  std::thread stop([&] { health.shutdown(); });
  while (reader->Read(&resp)) {
  }
  stop.join();
  EXPECT_NE(health_of(address).find("cannot reach"), std::string::npos);
}

TEST(HealthServer, RefusesAnAddressInUse) {
  rpc::HealthServer first, second;
  auto port = first.start("127.0.0.1:0");
  ASSERT_TRUE(port.ok());
  auto again = second.start("127.0.0.1:" + std::to_string(*port));
  ASSERT_FALSE(again.ok());
  EXPECT_NE(again.status().message().find("--health 127.0.0.1:"), std::string::npos);
}

// The drain as logic: a Coordinator without a network.
TEST(CoordinatorDrain, RefusesNewWorkAndWaitsForTheBandsInFlight) {
  const auto dir = testing_farm::temp_dir();
  CoordinatorOptions o;
  o.data_dir = (dir / "data").string();
  o.tick = Millis(20);
  std::string job_id;
  {
    Coordinator c(o);
    ASSERT_TRUE(c.start().ok());
    auto job = c.submit(testing_farm::request(testing_farm::kSpheres, 16, 8, 1, 1, 2, "d.png"));
    ASSERT_TRUE(job.ok()) << job.status().message();
    job_id = job->job_id;
    const std::string w = c.register_worker("host:1", 1)->worker_id;
    auto leased = c.lease_band(w, Millis(0), nullptr);
    ASSERT_TRUE(leased.ok() && leased->has_value());

    c.drain();
    auto refused = c.submit(testing_farm::request(testing_farm::kSpheres, 16, 8, 1, 1, 2, "e.png"));
    ASSERT_FALSE(refused.ok());
    EXPECT_EQ(refused.status().code(), Code::kUnavailable);
    auto none = c.lease_band(w, Millis(100), nullptr);
    ASSERT_TRUE(none.ok());
    EXPECT_FALSE(none->has_value()) << "no new lease while draining";
    EXPECT_FALSE(c.wait_drained(Millis(50))) << "a band is in flight";

    // The band in flight comes back and is accepted.
    const BandLease& t = **leased;
    BandOutput out;
    out.worker_id = w;
    out.lease_id = t.lease_id;
    out.rgb.assign(static_cast<size_t>(t.width) * (t.y1 - t.y0) * 3, 0.25f);
    auto accepted = c.complete_band(out);
    ASSERT_TRUE(accepted.ok() && accepted->accepted);
    EXPECT_TRUE(c.wait_drained(Millis(2000)));
    c.shutdown();
  }
  // Recorded in the store: a restart knows the band is done.
  Coordinator again(o);
  ASSERT_TRUE(again.start().ok());
  EXPECT_EQ(again.job(job_id)->bands_done, 1);
  again.shutdown();
  std::error_code ec;
  fs::remove_all(dir, ec);
}

// Over the wire: readiness on both ports, then a drain with a band in
// flight, as SIGTERM does it.
TEST_F(FarmTest, HealthAndDrainOverLoopback) {
  start();
  auto health_port = server_->serve_health("127.0.0.1:0");
  ASSERT_TRUE(health_port.ok()) << health_port.status().message();
  const std::string health = "127.0.0.1:" + std::to_string(*health_port);
  EXPECT_EQ(health_of(health), "SERVING");
  EXPECT_EQ(health_of(address_), "SERVING") << "the main port answers too";

  const SubmitRequest r = testing_farm::request(testing_farm::kSpheres, 16, 8, 1, 1, 2, "h.png");
  auto job = client_->submit(r);
  ASSERT_TRUE(job.ok()) << job.status().message();
  auto stub = worker_stub(worker_creds_);
  grpc::ClientContext c1, c2;
  prepare(c1);
  v1::RegisterResponse who;
  ASSERT_TRUE(stub->Register(&c1, v1::RegisterRequest(), &who).ok());
  v1::GetTaskRequest get;
  get.set_worker_id(who.worker_id());
  v1::GetTaskResponse leased;
  prepare(c2);
  ASSERT_TRUE(stub->GetTask(&c2, get, &leased).ok());
  ASSERT_TRUE(leased.has_task());

  auto drained =
      std::async(std::launch::async, [this] { server_->drain(Millis(10000), Millis(500)); });
  for (int i = 0; i < 100 && health_of(health) != "NOT_SERVING"; ++i)
    std::this_thread::sleep_for(Millis(20));
  EXPECT_EQ(health_of(health), "NOT_SERVING");
  EXPECT_EQ(health_of(health, rpc::kLivenessService), "SERVING") << "draining is not dead";
  EXPECT_EQ(health_of(address_), "NOT_SERVING");
  // One raw call (FarmClient would retry it for a while, as it should).
  auto conn = rpc::connect(address_, client_creds_);
  ASSERT_TRUE(conn.ok());
  auto client_stub = v1::ClientService::NewStub(conn->channel);
  v1::SubmitJobRequest submit;
  *submit.mutable_spec() =
      rpc::ToProto(testing_farm::request(testing_farm::kSpheres, 16, 8, 1, 1, 2, "i.png"));
  v1::SubmitJobResponse submitted;
  grpc::ClientContext cs;
  rpc::prepare(cs, *conn, Millis(5000));
  const grpc::Status refused = client_stub->SubmitJob(&cs, submit, &submitted);
  EXPECT_EQ(refused.error_code(), grpc::StatusCode::UNAVAILABLE);
  EXPECT_NE(refused.error_message().find("shutting down"), std::string::npos)
      << refused.error_message();

  v1::CompleteBandRequest result;
  result.set_worker_id(who.worker_id());
  result.set_lease_id(leased.task().lease_id());
  const int rows = leased.task().y1() - leased.task().y0();
  for (int i = 0; i < 16 * rows * 3; ++i) result.add_rgb(0.5f);
  v1::CompleteBandResponse answer;
  grpc::ClientContext c3;
  prepare(c3);
  ASSERT_TRUE(stub->CompleteBand(&c3, result, &answer).ok());
  EXPECT_TRUE(answer.accepted()) << answer.reason();
  ASSERT_EQ(drained.wait_for(std::chrono::seconds(10)), std::future_status::ready);
  EXPECT_NE(health_of(health).find("cannot reach"), std::string::npos);

  // The store was flushed and closed: a new coordinator on the same
  // directory has the band.
  server_.reset();
  coordinator_.reset();
  Coordinator again(options_);
  ASSERT_TRUE(again.start().ok());
  EXPECT_EQ(again.job(job->job_id)->bands_done, 1);
  again.shutdown();
}

}  // namespace
}  // namespace locus::farm

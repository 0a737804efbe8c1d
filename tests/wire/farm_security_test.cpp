// The farm's security and limits (docs/farm.md "Security", "Limits"):
// tokens and roles, TLS and mutual TLS with certificates made at test time
// (tests/tls/make_certs.sh), the coordinator's refusal to start unsafe,
// limits at submit, and confined output and mesh paths. Servers listen on
// 127.0.0.1 only.
#include <sys/stat.h>

#include <cstdlib>
#include <fstream>

#include "common/farm/auth.h"
#include "common/farm/paths.h"
#include "server/handlers.h"
#include "tests/farm_fixture.h"

namespace locus::farm {
namespace {
using namespace testing_farm;

void write_file(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

// ---------------------------------------------------------------- tokens

TEST(Authenticator, RolesAndRefusals) {
  const Authenticator auth = Authenticator::from_tokens({"c1", "both"}, {"w1", "both"});
  const char* m = "ClientService.SubmitJob";
  EXPECT_TRUE(auth.check(Role::kClient, "Bearer c1", false, m).ok());
  EXPECT_TRUE(auth.check(Role::kWorker, "Bearer w1", false, m).ok());
  EXPECT_TRUE(auth.check(Role::kClient, "Bearer both", false, m).ok());
  EXPECT_TRUE(auth.check(Role::kWorker, "Bearer both", false, m).ok());

  EXPECT_EQ(auth.check(Role::kClient, "", false, m).code(), Code::kUnauthenticated);
  EXPECT_EQ(auth.check(Role::kClient, "Basic c1", false, m).code(), Code::kUnauthenticated);
  EXPECT_EQ(auth.check(Role::kClient, "Bearer ", false, m).code(), Code::kUnauthenticated);
  EXPECT_EQ(auth.check(Role::kClient, "Bearer c1x", false, m).code(), Code::kUnauthenticated);
  EXPECT_EQ(auth.check(Role::kClient, "Bearer c", false, m).code(), Code::kUnauthenticated);
  const Status wrong_role = auth.check(Role::kClient, "Bearer w1", false, m);
  EXPECT_EQ(wrong_role.code(), Code::kPermissionDenied);
  EXPECT_NE(wrong_role.message().find("a worker token may not"), std::string::npos)
      << wrong_role.message();
  EXPECT_EQ(auth.check(Role::kWorker, "Bearer c1", false, m).code(), Code::kPermissionDenied);
  // Messages name the call, never the token.
  const Status unknown = auth.check(Role::kClient, "Bearer secret-value", false, m);
  EXPECT_NE(unknown.message().find(m), std::string::npos);
  EXPECT_EQ(unknown.message().find("secret-value"), std::string::npos);

  // Open (--insecure without token files): anything goes.
  const Authenticator open;
  EXPECT_FALSE(open.enforcing());
  EXPECT_TRUE(open.check(Role::kWorker, "", false, m).ok());
}

TEST(Authenticator, WorkerCertificateUnderMutualTls) {
  Authenticator auth = Authenticator::from_tokens({"c"}, {"w"});
  auth.require_worker_certificate(true);
  const Status no_cert = auth.check(Role::kWorker, "Bearer w", false, "WorkerService.Register");
  EXPECT_EQ(no_cert.code(), Code::kUnauthenticated);
  EXPECT_NE(no_cert.message().find("client certificate"), std::string::npos);
  EXPECT_TRUE(auth.check(Role::kWorker, "Bearer w", true, "WorkerService.Register").ok());
  // Clients need no certificate.
  EXPECT_TRUE(auth.check(Role::kClient, "Bearer c", false, "ClientService.ListJobs").ok());
  // A certificate does not replace the token.
  EXPECT_EQ(auth.check(Role::kWorker, "", true, "WorkerService.Register").code(),
            Code::kUnauthenticated);
}

TEST(Authenticator, TokenFiles) {
  const fs::path dir = temp_dir();
  write_file(dir / "clients", "# people\n\n  alice alice-token  \r\nbob-token\n");
  write_file(dir / "admins", "root\troot-token\nops-token\n");
  write_file(dir / "workers", "worker-token\n");
  write_file(dir / "empty", "# nothing\n\n");
  write_file(dir / "spaces", "a name and words\n");
  auto auth = Authenticator::from_files((dir / "clients").string(), (dir / "workers").string());
  ASSERT_TRUE(auth.ok()) << auth.status().message();
  EXPECT_TRUE(auth->check(Role::kClient, "Bearer alice-token", false, "x").ok());
  EXPECT_TRUE(auth->check(Role::kClient, "Bearer bob-token", false, "x").ok());
  EXPECT_EQ(auth->check(Role::kClient, "Bearer # people", false, "x").code(),
            Code::kUnauthenticated);
  EXPECT_EQ(auth->check(Role::kClient, "Bearer worker-token", false, "x").code(),
            Code::kPermissionDenied);
  // Users: named by their line, or after its number; admins from their file.
  EXPECT_EQ(auth->identify(Role::kClient, "Bearer alice-token", false, "x")->user, "alice");
  EXPECT_FALSE(auth->identify(Role::kClient, "Bearer alice-token", false, "x")->admin);
  EXPECT_EQ(auth->identify(Role::kClient, "Bearer bob-token", false, "x")->user, "token-4");
  auto with_admins = Authenticator::from_files((dir / "clients").string(),
                                               (dir / "workers").string(), (dir / "admins").string());
  ASSERT_TRUE(with_admins.ok()) << with_admins.status().message();
  auto root = with_admins->identify(Role::kClient, "Bearer root-token", false, "x");
  ASSERT_TRUE(root.ok());
  EXPECT_EQ(root->user, "root");
  EXPECT_TRUE(root->admin);
  EXPECT_EQ(with_admins->identify(Role::kClient, "Bearer ops-token", false, "x")->user, "admin-2");
  EXPECT_EQ(with_admins->identify(Role::kWorker, "Bearer root-token", false, "x").status().code(),
            Code::kPermissionDenied);
  EXPECT_TRUE(Authenticator().identify(Role::kClient, "", false, "x")->admin);  // no tokens

  auto empty = Authenticator::from_files((dir / "empty").string(), (dir / "workers").string());
  ASSERT_FALSE(empty.ok());
  EXPECT_NE(empty.status().message().find("--client-tokens"), std::string::npos);
  EXPECT_NE(empty.status().message().find("holds no token"), std::string::npos);
  auto missing = Authenticator::from_files((dir / "clients").string(), (dir / "nope").string());
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.status().message().find("--worker-tokens"), std::string::npos);
  auto spaces = Authenticator::from_files((dir / "spaces").string(), (dir / "workers").string());
  ASSERT_FALSE(spaces.ok());
  EXPECT_NE(spaces.status().message().find("spaces:1"), std::string::npos)
      << spaces.status().message();

  // Clients: --token-file first, then LOCUS_TOKEN.
  setenv("LOCUS_TOKEN", " from-env \n", 1);
  EXPECT_EQ(*load_token(""), "from-env");
  EXPECT_EQ(*load_token((dir / "workers").string()), "worker-token");
  unsetenv("LOCUS_TOKEN");
  EXPECT_EQ(*load_token(""), "");
  EXPECT_FALSE(load_token((dir / "nope").string()).ok());

  auto a = random_token(), b = random_token();
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(a->size(), 64u);
  EXPECT_NE(*a, *b);
  fs::remove_all(dir);
}

TEST(ServerSecurity, UnsafeConfigurationsAreRefused) {
  rpc::ServerSecurity s;
  Status st = rpc::check_server_security(s);
  EXPECT_EQ(st.code(), Code::kFailedPrecondition);
  EXPECT_NE(st.message().find("refusing to serve without TLS"), std::string::npos);
  s.tls_cert = "server.pem";
  s.tls_key = "server.key";
  st = rpc::check_server_security(s);
  EXPECT_NE(st.message().find("refusing to serve without tokens"), std::string::npos);
  s.auth = Authenticator::from_tokens({"c"}, {"w"});
  EXPECT_TRUE(rpc::check_server_security(s).ok());
  s.tls_key.clear();
  EXPECT_NE(rpc::check_server_security(s).message().find("go together"), std::string::npos);
  rpc::ServerSecurity ca_only;
  ca_only.insecure = true;
  ca_only.tls_ca = "ca.pem";
  EXPECT_EQ(rpc::check_server_security(ca_only).code(), Code::kInvalidArgument);
  rpc::ServerSecurity insecure;
  insecure.insecure = true;
  EXPECT_TRUE(rpc::check_server_security(insecure).ok());
}

TEST(Connect, PlaintextOnlyToLoopbackUnlessInsecure) {
  EXPECT_TRUE(rpc::is_loopback("127.0.0.1:7000"));
  EXPECT_TRUE(rpc::is_loopback("127.3.2.1:1"));
  EXPECT_TRUE(rpc::is_loopback("localhost:7000"));
  EXPECT_TRUE(rpc::is_loopback("[::1]:7000"));
  EXPECT_TRUE(rpc::is_loopback("ipv4:127.0.0.1:7000"));
  EXPECT_FALSE(rpc::is_loopback("128.0.0.1:7000"));
  EXPECT_FALSE(rpc::is_loopback("farm.example:7000"));
  EXPECT_FALSE(rpc::is_loopback("127.0.0.1.example:7000"));
  // Refused before any channel exists: nothing is sent anywhere.
  auto remote = rpc::connect("192.0.2.10:7000", Credentials());
  ASSERT_FALSE(remote.ok());
  EXPECT_NE(remote.status().message().find("--tls-ca"), std::string::npos);
  EXPECT_NE(remote.status().message().find("--insecure"), std::string::npos);
  Credentials half;
  half.tls_cert = "client.pem";
  EXPECT_FALSE(rpc::connect("127.0.0.1:7000", half).ok());
  Credentials unreadable;
  unreadable.tls_ca = "/nonexistent/ca.pem";
  auto bad = rpc::connect("127.0.0.1:7000", unreadable);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("/nonexistent/ca.pem"), std::string::npos);
}

// Over the network: plaintext on loopback, tokens enforced (the fixture's
// default).
TEST_F(FarmTest, TokensAndRolesOverTheWire) {
  start();
  const SubmitRequest r = request(kSpheres, 32, 24, 1, 1, 2, "t.png");

  FarmClient anonymous(address_, Credentials());
  auto refused = anonymous.submit(r);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), Code::kUnauthenticated);
  EXPECT_NE(refused.status().message().find("UNAUTHENTICATED"), std::string::npos);
  EXPECT_EQ(anonymous.jobs().status().code(), Code::kUnauthenticated);

  Credentials wrong;
  wrong.token = "not-a-token-of-this-farm";
  EXPECT_EQ(FarmClient(address_, wrong).jobs().status().code(), Code::kUnauthenticated);

  // A client holding a worker token: PERMISSION_DENIED, and nothing stored.
  FarmClient as_worker(address_, worker_creds_);
  auto denied = as_worker.submit(r);
  ASSERT_FALSE(denied.ok());
  EXPECT_EQ(denied.status().code(), Code::kPermissionDenied);
  EXPECT_NE(denied.status().message().find("PERMISSION_DENIED"), std::string::npos);
  EXPECT_EQ(as_worker.cancel("j0001").status().code(), Code::kPermissionDenied);
  EXPECT_TRUE(client_->jobs()->empty());

  // A worker holding a client token: refused on every WorkerService call.
  auto stub = worker_stub(client_creds_);
  for (int call = 0; call < 3; ++call) {
    grpc::ClientContext ctx;
    rpc::Connection c;
    c.token = kClientToken;
    rpc::prepare(ctx, c, Millis(5000));
    grpc::Status st;
    if (call == 0) {
      v1::RegisterResponse resp;
      st = stub->Register(&ctx, v1::RegisterRequest(), &resp);
    } else if (call == 1) {
      v1::GetTaskRequest req;
      req.set_worker_id("w0001");
      v1::GetTaskResponse resp;
      st = stub->GetTask(&ctx, req, &resp);
    } else {
      v1::CompleteBandRequest req;
      req.set_worker_id("w0001");
      req.set_lease_id("x");
      v1::CompleteBandResponse resp;
      st = stub->CompleteBand(&ctx, req, &resp);
    }
    EXPECT_EQ(st.error_code(), grpc::StatusCode::PERMISSION_DENIED) << call << st.error_message();
  }
  WorkerOptions o;
  o.coordinator = address_;
  o.credentials = client_creds_;
  WorkerClient impostor(o);
  EXPECT_EQ(impostor.run(), 1);  // gives up at once: retrying would not help
  EXPECT_TRUE(client_->workers()->empty());

  // The right tokens work.
  add_workers(1);
  expect_identical(run(r), r);
}

// ---------------------------------------------------------------- TLS

class FarmTlsTest : public FarmTest {
 protected:
  static void SetUpTestSuite() {
    certs_ = new fs::path(temp_dir());
    const std::string cmd = "bash " + std::string(LOCUS_SOURCE_DIR) + "/tests/tls/make_certs.sh " +
                            certs_->string() + " >/dev/null 2>&1";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  }
  static void TearDownTestSuite() {
    std::error_code ec;
    fs::remove_all(*certs_, ec);
    delete certs_;
  }
  static std::string cert(const char* name) { return (*certs_ / name).string(); }

  // TLS with the test CA; mutual TLS for workers when `mutual`.
  void start_tls(bool mutual) {
    server_security_.insecure = false;
    server_security_.tls_cert = cert("server.pem");
    server_security_.tls_key = cert("server.key");
    if (mutual) server_security_.tls_ca = cert("ca.pem");
    client_creds_.tls_ca = cert("ca.pem");
    worker_creds_.tls_ca = cert("ca.pem");
    start();
  }
  void give_workers_certificates() {
    worker_creds_.tls_cert = cert("client.pem");
    worker_creds_.tls_key = cert("client.key");
  }

  static fs::path* certs_;
};
fs::path* FarmTlsTest::certs_ = nullptr;

TEST_F(FarmTlsTest, ValidClientOverTlsRendersFramesEqualToALocalRender) {
  start_tls(/*mutual=*/true);
  give_workers_certificates();
  add_workers(2);
  const SubmitRequest r = request(kGlass, 48, 36, 1, 2, 3, "tls_####.png", 20.0);
  expect_identical(run(r), r);
}

TEST_F(FarmTlsTest, ClientsThatCannotVerifyTheServerAreRefused) {
  start_tls(/*mutual=*/false);
  // Plaintext against TLS: the handshake fails; the message points at --tls-ca.
  FarmClient plain(address_, [] {
    Credentials c;
    c.token = kClientToken;
    return c;
  }());
  auto r = plain.jobs();
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Code::kUnavailable);
  EXPECT_NE(r.status().message().find("--tls-ca"), std::string::npos) << r.status().message();
  // A CA that did not sign the server's certificate.
  Credentials other = client_creds_;
  other.tls_ca = cert("other-ca.pem");
  EXPECT_EQ(FarmClient(address_, other).jobs().status().code(), Code::kUnavailable);
  // The right CA, but no token: TLS alone is not enough.
  Credentials no_token = client_creds_;
  no_token.token.clear();
  EXPECT_EQ(FarmClient(address_, no_token).jobs().status().code(), Code::kUnauthenticated);
  EXPECT_TRUE(client_->jobs().ok());
}

TEST_F(FarmTlsTest, MutualTlsRefusesAWorkerWithoutAClientCertificate) {
  start_tls(/*mutual=*/true);
  // A clean TLS connection with a valid worker token, but no certificate.
  auto stub = worker_stub(worker_creds_);
  grpc::ClientContext ctx;
  prepare(ctx);
  v1::RegisterResponse resp;
  const grpc::Status st = stub->Register(&ctx, v1::RegisterRequest(), &resp);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_NE(st.error_message().find("client certificate"), std::string::npos)
      << st.error_message();
  WorkerOptions o;
  o.coordinator = address_;
  o.credentials = worker_creds_;
  WorkerClient no_cert(o);
  EXPECT_EQ(no_cert.run(), 1);
  // Clients need none.
  EXPECT_TRUE(client_->jobs().ok());
  // With the certificate the worker registers.
  give_workers_certificates();
  add_workers(1);
  for (int i = 0; i < 200 && client_->workers()->empty(); ++i) std::this_thread::sleep_for(Millis(20));
  EXPECT_EQ(client_->workers()->size(), 1u);
}

// ---------------------------------------------------------------- limits

TEST_F(FarmTest, LimitsGiveClearErrorsAtSubmit) {
  options_.limits.max_resolution = 64;
  options_.limits.max_objects = 3;
  options_.limits.max_frames = 5;
  options_.limits.max_bands = 12;
  options_.limits.max_jobs = 1;
  start();
  auto expect_refused = [&](const SubmitRequest& r, Code code, const std::string& flag) {
    auto s = client_->submit(r);
    ASSERT_FALSE(s.ok()) << flag;
    EXPECT_EQ(s.status().code(), code) << s.status().message();
    EXPECT_NE(s.status().message().find(flag), std::string::npos) << flag << ": " << s.status().message();
  };
  // spheres.json has 4 objects; without the last, 3: within --max-objects.
  auto small = [](int w, int first, int last, int bands, const std::string& out) {
    SubmitRequest r = request(kSpheres, w, 24, first, last, bands, out);
    r.scene.mutable_objects()->RemoveLast();
    return r;
  };
  expect_refused(request(kSpheres, 32, 24, 1, 1, 1, "x.png"), Code::kInvalidArgument,
                 "--max-objects");
  expect_refused(small(65, 1, 1, 1, "x.png"), Code::kInvalidArgument, "--max-resolution");
  expect_refused(small(32, 1, 6, 1, "x_#.png"), Code::kInvalidArgument, "--max-frames");
  expect_refused(small(32, 1, 5, 3, "x_#.png"), Code::kInvalidArgument, "--max-bands");
  EXPECT_TRUE(client_->jobs()->empty());

  auto first = client_->submit(small(64, 1, 4, 3, "x_#.png"));  // at every limit
  ASSERT_TRUE(first.ok()) << first.status().message();
  expect_refused(small(32, 1, 1, 1, "y.png"), Code::kResourceExhausted, "--max-jobs");
  ASSERT_TRUE(client_->cancel(first->job_id).ok());
  EXPECT_TRUE(client_->submit(small(32, 1, 1, 1, "y.png")).ok());
}

TEST_F(FarmTest, ServerMessageSizeLimitIsExplicit) {
  start();
  // A channel without the farm's send limit, so that the server's own
  // receive limit is what refuses.
  grpc::ChannelArguments args;
  args.SetMaxSendMessageSize(-1);
  auto stub = v1::WorkerService::NewStub(
      grpc::CreateCustomChannel(address_, grpc::InsecureChannelCredentials(), args));
  v1::CompleteBandRequest big;
  big.set_worker_id("w0001");
  big.set_lease_id("x");
  big.mutable_rgb()->Resize(kMaxMessageBytes / 4 + 16, 0.0f);
  grpc::ClientContext ctx;
  prepare(ctx, Millis(30000));
  v1::CompleteBandResponse resp;
  const grpc::Status st = stub->CompleteBand(&ctx, big, &resp);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << st.error_message();
  // And the farm's own channels refuse to send it at all.
  auto own = worker_stub(worker_creds_);
  grpc::ClientContext ctx2;
  prepare(ctx2, Millis(30000));
  EXPECT_EQ(own->CompleteBand(&ctx2, big, &resp).error_code(),
            grpc::StatusCode::RESOURCE_EXHAUSTED);
  // The coordinator is still serving.
  EXPECT_TRUE(client_->jobs().ok());
}

// ---------------------------------------------------------------- paths

TEST_F(FarmTest, OutputPathsAreConfined) {
  start();
  for (const std::string out : {"../x.png", "/etc/x.png", "a/../../x.png", "..", "/x_####.png"}) {
    auto s = client_->submit(request(kSpheres, 32, 24, 1, 1, 1, out));
    ASSERT_FALSE(s.ok()) << out;
    EXPECT_EQ(s.status().code(), Code::kInvalidArgument) << out;
    EXPECT_NE(s.status().message().find(out), std::string::npos) << s.status().message();
  }
  EXPECT_TRUE(client_->jobs()->empty());
  // A relative directory is harmless: the frame is written under the
  // job's directory of the output root, by its file name.
  add_workers(1);
  const JobInfo job = run(request(kSpheres, 32, 24, 1, 1, 1, "shots/x.png"));
  ASSERT_EQ(job.state, JobState::kSucceeded) << job.error;
  EXPECT_TRUE(fs::exists(fs::path(coordinator_->job_dir(job.job_id)) / "x.png"));
  EXPECT_EQ(fs::path(coordinator_->job_dir(job.job_id)).parent_path(),
            fs::path(options_.data_dir) / "jobs");
}

TEST(Paths, ConfinePathStaysInsideTheRoot) {
  const fs::path dir = temp_dir();
  const fs::path root = dir / "meshes";
  fs::create_directories(root / "sub");
  fs::create_directories(dir / "meshes2");
  write_file(root / "ok.obj", "v 0 0 0\n");
  write_file(dir / "secret.obj", "v 1 1 1\n");
  fs::create_symlink(dir / "secret.obj", root / "link.obj");
  fs::create_symlink(dir, root / "up");

  EXPECT_EQ(*confine_path(root, "ok.obj", "mesh"), fs::canonical(root / "ok.obj"));
  EXPECT_TRUE(confine_path(root, "sub/new.obj", "mesh").ok());  // need not exist yet
  EXPECT_TRUE(confine_path(root, (root / "ok.obj").string(), "mesh").ok());
  for (const std::string& bad : std::vector<std::string>{"../secret.obj", "sub/../../secret.obj", "sub/../ok.obj", "/etc/passwd",
        (dir / "meshes2" / "x.obj").string(), "link.obj", "up/secret.obj", ""}) {
    auto r = confine_path(root, bad, "objects[0].mesh.obj");
    ASSERT_FALSE(r.ok()) << bad;
    EXPECT_EQ(r.status().code(), Code::kInvalidArgument) << bad;
    EXPECT_NE(r.status().message().find("objects[0].mesh.obj"), std::string::npos);
  }
  EXPECT_TRUE(check_plain_file_name("f_0001.png", "file").ok());
  for (const std::string bad : {"", ".", "..", "../x.png", "/etc/x", "a/b.png", "x\ny.png"})
    EXPECT_FALSE(check_plain_file_name(bad, "file").ok()) << bad;
  fs::remove_all(dir);
}

// A scene naming an OBJ file: refused without a mesh root, confined with
// one, on the coordinator (at submit) and on the worker (BandRenderer).
TEST_F(FarmTest, MeshPathsAreConfinedOnCoordinatorAndWorker) {
  const fs::path root = dir_ / "meshes";
  fs::create_directories(root);
  write_file(root / "tri.obj", "v -1 0 0\nv 1 0 0\nv 0 2 0\nf 1 2 3\n");
  write_file(dir_ / "outside.obj", "v -1 0 0\nv 1 0 0\nv 0 2 0\nf 1 2 3\n");
  auto with_obj = [&](const std::string& obj) {
    SubmitRequest r = request(kSpheres, 32, 24, 1, 1, 1, "m.png");
    v1::Object* o = r.scene.add_objects();
    o->mutable_mesh()->set_obj(obj);
    o->set_material(3);
    return r;
  };
  options_.mesh_root = root.string();
  start();
  for (const std::string& bad :
       std::vector<std::string>{"../outside.obj", (dir_ / "outside.obj").string(), "/etc/passwd"}) {
    auto s = client_->submit(with_obj(bad));
    ASSERT_FALSE(s.ok()) << bad;
    EXPECT_EQ(s.status().code(), Code::kInvalidArgument);
    EXPECT_NE(s.status().message().find("objects[4].mesh.obj"), std::string::npos)
        << s.status().message();
  }
  ASSERT_TRUE(client_->submit(with_obj("tri.obj")).ok());

  // The worker checks again against its own root, whatever the coordinator.
  v1::Scene escaping = with_obj("../outside.obj").scene;
  BandRenderer no_root(1);
  Status s = no_root.add_scene("a", with_obj("tri.obj").scene, "job scene");
  EXPECT_EQ(s.code(), Code::kInvalidArgument);
  EXPECT_NE(s.message().find("inline"), std::string::npos) << s.message();
  BandRenderer rooted(1, root.string());
  EXPECT_EQ(rooted.add_scene("b", escaping, "job scene").code(), Code::kInvalidArgument);
  EXPECT_EQ(rooted.add_scene("c", with_obj("/etc/passwd").scene, "job scene").code(),
            Code::kInvalidArgument);
  EXPECT_FALSE(rooted.has_scene("b"));
  ASSERT_TRUE(rooted.add_scene("d", with_obj("tri.obj").scene, "job scene").ok());
  BandLease t;
  t.scene_hash = "d";
  t.frame = t.frame_first = t.frame_last = 1;
  t.width = 32;
  t.height = 24;
  t.y1 = 24;
  EXPECT_TRUE(rooted.render(t).ok());
  // Oversized bands from a coordinator are refused, not attempted.
  t.width = kMaxResolution + 1;
  EXPECT_EQ(rooted.render(t).status().code(), Code::kInvalidArgument);
}

}  // namespace
}  // namespace locus::farm

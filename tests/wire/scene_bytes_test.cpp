// GetScene sends the scene's stored bytes (GetSceneResponse.scene, a
// serialized Scene): the bytes the client's scene serializes to, under their
// content hash; on the wire the same as the Scene message the field was
// before, so that a worker or a coordinator of an older release reads it.
#include "common/farm/types.h"
#include "tests/farm_fixture.h"
#include "tests/wire/hand_worker.h"

namespace locus::farm {
namespace {
using namespace testing_farm;

using SceneBytesTest = HandWorkerTest;

TEST_F(SceneBytesTest, AWorkerGetsTheStoredSceneAsAnOlderReleaseSentIt) {
  const SubmitRequest r = request(kSpheres, 32, 24, 1, 1, 1, "s.png");
  const std::string job = start_with_job(r);
  ASSERT_FALSE(job.empty());
  HandWorker w = hand_worker();
  const std::optional<v1::BandTask> task = w.lease();
  ASSERT_TRUE(task);
  const v1::GetSceneResponse resp = w.scene(task->scene_hash());
  EXPECT_EQ(resp.scene(), r.scene.SerializeAsString());
  EXPECT_EQ(content_hash(resp.scene()), task->scene_hash());
  // An older worker read field 1 as a Scene message: JobSpec's field 1 is
  // one, and reads the answer's bytes as that scene.
  v1::JobSpec older_reading;
  ASSERT_TRUE(older_reading.ParseFromString(resp.SerializeAsString()));
  EXPECT_EQ(older_reading.scene().SerializeAsString(), r.scene.SerializeAsString());
  // An older coordinator's answer (the Scene message as field 1) read here.
  v1::JobSpec older_answer;
  *older_answer.mutable_scene() = r.scene;
  v1::GetSceneResponse read;
  ASSERT_TRUE(read.ParseFromString(older_answer.SerializeAsString()));
  EXPECT_EQ(read.scene(), r.scene.SerializeAsString());
  // The band renders from those bytes, and the frame is a single process's.
  v1::CompleteBandRequest done = w.render(*task, false);
  v1::CompleteBandResponse answer;
  ASSERT_TRUE(w.send(done, &answer).ok());
  EXPECT_TRUE(answer.accepted()) << answer.reason();
  EXPECT_TRUE(succeeded(job, r));
}

TEST(BandRendererBytes, BytesThatAreNoSceneAreRefusedByName) {
  BandRenderer renderer(1);
  const Status s = renderer.add_scene_bytes("h", std::string("\xff\xff\xff", 3), "job j1 scene");
  EXPECT_EQ(s.code(), Code::kInvalidArgument);
  EXPECT_NE(s.message().find("job j1 scene"), std::string::npos) << s.message();
  EXPECT_FALSE(renderer.has_scene("h"));
}

}  // namespace
}  // namespace locus::farm

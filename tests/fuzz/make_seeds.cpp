// Writes the coordinator fuzzer's seed corpus (tests/fuzz/corpus/
// coordinator/): request sequences a real client and worker send, so that
// fuzzing starts from deep states (a job submitted, a band leased, pixels
// returned, a frame written). Run by hand after a protocol change:
//   build-fuzz/bin/locus_fuzz_seeds SCENE.json OUT_DIR
#include <cstdio>
#include <fstream>
#include <string>

#include "common/scene/scene_io.h"
#include "proto/locus.pb.h"
#include "tests/fuzz/coordinator_input.h"

using namespace locus;
using namespace locus::fuzz;

namespace {

std::string bytes(const google::protobuf::Message& m) { return m.SerializeAsString(); }

v1::SubmitJobRequest submit(const v1::Scene& scene, int w, int h, int first, int last, int bands,
                            const std::string& output) {
  v1::SubmitJobRequest r;
  v1::JobSpec* s = r.mutable_spec();
  *s->mutable_scene() = scene;
  s->set_scene_name("seed.json");
  s->set_width(w);
  s->set_height(h);
  s->set_frame_first(first);
  s->set_frame_last(last);
  s->set_bands(bands);
  s->set_output(output);
  return r;
}

void write(const std::string& dir, const std::string& name, const std::string& input) {
  std::ofstream(dir + "/" + name, std::ios::binary) << input;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s SCENE.json OUT_DIR\n", argv[0]);
    return 2;
  }
  auto scene = load_scene(argv[1]);
  if (!scene.ok()) {
    std::fprintf(stderr, "%s\n", scene.status().message().c_str());
    return 1;
  }
  const v1::Scene proto = scene_to_proto(*scene);
  const std::string dir = argv[2];
  const uint8_t F = kFillIds;

  // A whole job: register, submit, take both bands, fetch the scene, return
  // right-sized pixels, heartbeat, look, fetch the written frame.
  std::string job;
  v1::RegisterRequest reg;
  reg.set_name("seed-worker");
  reg.set_threads(1);
  append_request(job, kRegister, bytes(reg));
  append_request(job, kSubmitJob, bytes(submit(proto, 8, 6, 1, 1, 2, "out/seed.png")));
  for (int band = 0; band < 2; ++band) {
    append_request(job, kGetTask | F, bytes(v1::GetTaskRequest()));
    append_request(job, kGetScene | F, bytes(v1::GetSceneRequest()));
    append_request(job, kHeartbeat | F, bytes(v1::HeartbeatRequest()));
    append_request(job, kCompleteBand | F | kRightSize, bytes(v1::CompleteBandRequest()));
  }
  append_request(job, kGetJob | F, bytes(v1::GetJobRequest()));
  append_request(job, kListWorkers, bytes(v1::ListWorkersRequest()));
  append_request(job, kWatchJob | F, bytes(v1::WatchJobRequest()));
  append_request(job, kFetchResults | F, bytes(v1::FetchResultsRequest()));
  write(dir, "whole_job", job);

  // An animation, a wrong-sized result, a worker error and a cancel.
  std::string anim;
  append_request(anim, kRegister, bytes(reg));
  auto a = submit(proto, 8, 4, 1, 3, 1, "a_####.exr");
  a.mutable_spec()->set_orbit_degrees(30);
  a.mutable_spec()->mutable_render()->set_method("local");
  a.mutable_spec()->mutable_render()->set_spp(2);
  append_request(anim, kSubmitJob, bytes(a));
  append_request(anim, kGetTask | F, bytes(v1::GetTaskRequest()));
  v1::CompleteBandRequest short_band;
  short_band.add_rgb(1.0f);
  append_request(anim, kCompleteBand | F, bytes(short_band));
  append_request(anim, kGetTask | F, bytes(v1::GetTaskRequest()));
  v1::CompleteBandRequest failed;
  failed.set_error("out of memory");
  append_request(anim, kCompleteBand | F, bytes(failed));
  append_request(anim, kCancelJob | F, bytes(v1::CancelJobRequest()));
  // Retried (a JobActionRequest of odd length), then frames requeued.
  v1::JobActionRequest retry;
  retry.set_job_id("x");
  append_request(anim, kPauseJob | F, bytes(retry));
  v1::RequeueJobRequest requeue;
  requeue.set_frame_first(1);
  requeue.set_frame_last(2);
  append_request(anim, kSetPriority | F | kRightSize, bytes(requeue));
  append_request(anim, kGetTask | F, bytes(v1::GetTaskRequest()));
  append_request(anim, kListJobs, bytes(v1::ListJobsRequest()));
  write(dir, "animation_cancel", anim);

  // Submissions the coordinator must refuse: paths out of the root, an OBJ
  // file, sizes past the limits, no frame field.
  std::string bad;
  append_request(bad, kSubmitJob, bytes(submit(proto, 8, 6, 1, 1, 1, "../x.png")));
  append_request(bad, kSubmitJob, bytes(submit(proto, 8, 6, 1, 1, 1, "/etc/x.png")));
  append_request(bad, kSubmitJob, bytes(submit(proto, 100000, 6, 1, 1, 1, "x.png")));
  append_request(bad, kSubmitJob, bytes(submit(proto, 8, 6, 1, 9999, 1, "x_#.png")));
  append_request(bad, kSubmitJob, bytes(submit(proto, 8, 6, 1, 3, 1, "x.png")));
  auto obj = submit(proto, 8, 6, 1, 1, 1, "x.png");
  obj.mutable_spec()->mutable_scene()->add_objects()->mutable_mesh()->set_obj("../../etc/passwd");
  append_request(bad, kSubmitJob, bytes(obj));
  v1::HeartbeatRequest hb;
  hb.set_worker_id("w9999");
  hb.add_lease_ids("nope");
  append_request(bad, kHeartbeat, bytes(hb));
  write(dir, "refusals", bad);
  return 0;
}

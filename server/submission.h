// A job submission on its way to the Scheduler, in the steps that need no
// coordinator state: the checks (the scene and the farm's limits, size,
// frames, render settings, output pattern, bands, request id; each refused
// with InvalidArgument naming the input and the limit's flag), the
// fingerprint that tells a retried submission from a reused request id, and
// the cost preview that places the band edges. Coordinator::submit runs the
// checks and the fingerprint before it takes its lock (docs/farm.md
// "Limits").
#pragma once

#include <string>
#include <vector>

#include "common/base/params.h"
#include "common/base/status.h"
#include "common/farm/types.h"
#include "common/scene/scene.h"

namespace locus::farm {

// A submission that passed check_submission(): the job's spec but for what
// needs the coordinator (scene_hash, bands, band_edges).
struct CheckedSubmission {
  std::string name;  // the scene's, for messages and logs (spec.scene_name)
  JobSpec spec;
  Scene scene;          // as the renderer reads it, for the cost preview
  RenderParams params;  // spec.render as the workers resolve it
};

// OBJ files a scene names are looked up under `mesh_root` only (empty:
// none, meshes inline).
Result<CheckedSubmission> check_submission(const SubmitRequest& request, const Limits& limits,
                                           const std::string& mesh_root);

// Hex SHA-256 of what makes a retry a retry: the same scene (spec.scene_hash)
// and the same request.
std::string submission_fingerprint(const SubmitRequest& request, const JobSpec& spec);

// Row edges of job.spec.bands bands of equal predicted cost (issue #9 item 4,
// docs/farm.md), from a point-sampled preview of the middle frame and used
// for every frame; empty (bands of equal height) when there is nothing to
// balance (one band, the ray tracer) or the preview fails (logged).
// `row_costs`, when given, gets the prediction of each row (the dashboard's
// band map), or nothing.
std::vector<int> cost_band_edges(const CheckedSubmission& job,
                                 std::vector<float>* row_costs = nullptr);

// A notification URL (`--notify-url`, the coordinator's --notify-urls) in
// parts: http or https, a host (a name, an IPv4 address or [an IPv6
// one]) without user information, a port (80 or 443 when absent) and a
// path ("/" when absent). InvalidArgument naming `what` and the problem.
struct HttpUrl {
  bool https = false;
  std::string host;  // as written, brackets of IPv6 removed
  int port = 80;
  std::string path;  // with its query
};
Result<HttpUrl> parse_http_url(const std::string& url, const std::string& what);
// Whether a job may ask to be told at `url`: it must fall under one of the
// coordinator's --notify-urls (same scheme, host and port, and a path
// under the allowed one). PermissionDenied naming the URL otherwise (no
// list: no notification URL is allowed).
Status check_notify_url(const std::string& url, const std::vector<std::string>& allowed);

}  // namespace locus::farm

// Threads for one frame: how many a render uses, and a loop whose
// iterations run side by side. The frame's preparation (paper §3 steps
// ii-iii: the scan scene, the occluders' shapes, each light's shadow
// volumes) runs its independent pieces through it; render_band shares
// rows among the same number of threads (common/render.cpp); write_exr
// compresses a frame's blocks with it (common/base/exr.cpp).
#pragma once

#include "common/base/function_ref.h"
#include "common/base/params.h"

namespace locus {

// The threads of a render: params.threads, or one per core for 0.
int render_threads(const RenderParams& params);

// Runs body(i) for every i in [0, n) on at most `threads` threads (the
// calling one among them), handing out indices in increasing order as
// threads become free, and returns when every one has run. The first
// exception a body throws is rethrown here (indices not yet started are
// then skipped).
//
// Determinism: body(i) writes only what belongs to i (its own slot of a
// vector sized beforehand) and reads nothing another index writes, so what
// the loop makes is the same, bit for bit, for any thread count and any
// timing; no sum or list is ever formed in the order threads finish.
void parallel_for(int n, int threads, FunctionRef<void(int)> body);

// The same over [0, n) cut into chunks of at least `grain` indices (about
// four per thread, so that a slow chunk does not leave a thread idle):
// body(begin, end) for each chunk. One chunk, on the calling thread, when
// n < 2 * grain.
void parallel_chunks(int n, int threads, int grain, FunctionRef<void(int, int)> body);

// How the loops above cut [0, n): into n / grain chunks, at least 1 and at
// most `most`; chunk c of `chunks` is [chunk_edge(n, c, chunks),
// chunk_edge(n, c + 1, chunks)).
int chunk_count(int n, int grain, int most);
inline int chunk_edge(int n, int c, int chunks) {
  return static_cast<int>(static_cast<long long>(n) * c / chunks);
}

}  // namespace locus

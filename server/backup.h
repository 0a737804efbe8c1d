// A copy of a coordinator's data directory taken while the coordinator runs
// (`locus-coordinator --data DIR backup OUT`): the job store through
// SQLite's online backup from a read-only connection, then the job
// directories' files that the copied store needs (band files of frames not
// yet written, written frames and movies). Restoring is starting a
// coordinator with `--data OUT` (docs/farm.md "Backup, restore and
// upgrade"). No network; the running coordinator's lock is not taken and
// its writes go on while the store is copied.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "common/base/status.h"

namespace locus::farm {

struct BackupOptions {
  std::string data_dir;     // --data: DIR/locus.db
  std::string output_root;  // --output-root: the job directories; empty: DIR/jobs
  std::string out;          // must not exist; its parent must
  // The store is copied this many pages at a time, with a pause between
  // steps, so that the coordinator's own reads and writes are never held
  // up for long.
  int pages_per_step = 256;
  int pause_ms = 1;
};

struct BackupReport {
  int64_t pages = 0;     // of the copied store
  int jobs = 0;          // in the copied store
  int band_files = 0;    // band files in OUT (accepted bands of frames not yet written)
  int job_files = 0;     // written frames and movies in OUT
  int linked = 0;        // files hard-linked (same filesystem) ...
  int copied = 0;        // ... or copied
  // Bands accepted during the backup whose frame was written before their
  // band file could be taken: the restored coordinator renders them again.
  std::vector<std::string> rendered_again;
};

// Writes the backup to a temporary directory beside OUT and renames it to
// OUT at the end, so an interrupted backup never looks complete. Fails,
// leaving nothing at OUT, when the store cannot be read or copied, when OUT
// exists, or when the data directory is inconsistent: a band the store says
// is accepted with neither its band file, its pixels in the store, nor its
// frame's file; a frame the store says is written without its file. Every
// such band and frame is named.
Result<BackupReport> backup_data_dir(const BackupOptions& options);

}  // namespace locus::farm

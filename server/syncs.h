// Every sync the coordinator asks of the disk, counted in the process
// (issue #25: "<= 2 fsyncs per 50 bands", counted): its own fsync and
// fdatasync calls (the group commit's log sync, the frames' and their
// directories') and SQLite's (each xSync of the store's files, through a
// VFS that wraps SQLite's default one and counts). The counts are what
// strace -c -e fsync,fdatasync counts, without a tracer slowing the
// process (docs/farm.md "Durability: the group commit"). SQLite's directory
// sync after it creates a journal or a log, which its unix VFS makes inside
// that file's first xSync, counts as one more.
#pragma once

#include <cstdint>

namespace locus::farm {

struct SyncCounts {
  uint64_t files = 0;  // the coordinator's own fsync and fdatasync calls
  uint64_t store = 0;  // SQLite's xSync calls
  uint64_t total() const { return files + store; }
};

// fsync(2) and fdatasync(2), counted.
int counted_fsync(int fd);
int counted_fdatasync(int fd);

// Makes SQLite's default VFS the counting one, once per process; every
// database opened after it is counted. JobStore::open calls it.
void count_store_syncs();

// Since the process started.
SyncCounts sync_counts();

}  // namespace locus::farm

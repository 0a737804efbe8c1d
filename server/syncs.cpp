#include "server/syncs.h"

#include <sqlite3.h>
#include <unistd.h>

#include <atomic>
#include <mutex>

namespace locus::farm {
namespace {

std::atomic<uint64_t> g_file_syncs{0};
std::atomic<uint64_t> g_store_syncs{0};

// ---- The counting VFS: every call goes to the default VFS it wraps
// (SQLite's "VFS shim" pattern); xSync is counted on the way.

sqlite3_vfs* g_real = nullptr;  // SQLite's default VFS before ours

// Our file, with the real VFS's file right behind it (szOsFile covers both).
struct CountingFile {
  sqlite3_file base;
  sqlite3_file* real;
  // A journal or log that SQLite created: its first xSync syncs the
  // directory too (the unix VFS's dirSync), a second fsync.
  bool directory_pending;
};
sqlite3_file* real_of(sqlite3_file* f) { return reinterpret_cast<CountingFile*>(f)->real; }
const sqlite3_io_methods* methods_of(sqlite3_file* f) { return real_of(f)->pMethods; }

int file_close(sqlite3_file* f) { return methods_of(f)->xClose(real_of(f)); }
int file_read(sqlite3_file* f, void* buf, int n, sqlite3_int64 off) {
  return methods_of(f)->xRead(real_of(f), buf, n, off);
}
int file_write(sqlite3_file* f, const void* buf, int n, sqlite3_int64 off) {
  return methods_of(f)->xWrite(real_of(f), buf, n, off);
}
int file_truncate(sqlite3_file* f, sqlite3_int64 size) {
  return methods_of(f)->xTruncate(real_of(f), size);
}
int file_sync(sqlite3_file* f, int flags) {
  auto* c = reinterpret_cast<CountingFile*>(f);
  g_store_syncs.fetch_add(c->directory_pending ? 2 : 1, std::memory_order_relaxed);
  c->directory_pending = false;
  return methods_of(f)->xSync(real_of(f), flags);
}
int file_size(sqlite3_file* f, sqlite3_int64* size) {
  return methods_of(f)->xFileSize(real_of(f), size);
}
int file_lock(sqlite3_file* f, int level) { return methods_of(f)->xLock(real_of(f), level); }
int file_unlock(sqlite3_file* f, int level) { return methods_of(f)->xUnlock(real_of(f), level); }
int file_check_reserved(sqlite3_file* f, int* out) {
  return methods_of(f)->xCheckReservedLock(real_of(f), out);
}
int file_control(sqlite3_file* f, int op, void* arg) {
  return methods_of(f)->xFileControl(real_of(f), op, arg);
}
int file_sector_size(sqlite3_file* f) { return methods_of(f)->xSectorSize(real_of(f)); }
int file_device(sqlite3_file* f) { return methods_of(f)->xDeviceCharacteristics(real_of(f)); }
int file_shm_map(sqlite3_file* f, int region, int size, int extend, void volatile** p) {
  return methods_of(f)->xShmMap(real_of(f), region, size, extend, p);
}
int file_shm_lock(sqlite3_file* f, int offset, int n, int flags) {
  return methods_of(f)->xShmLock(real_of(f), offset, n, flags);
}
void file_shm_barrier(sqlite3_file* f) { methods_of(f)->xShmBarrier(real_of(f)); }
int file_shm_unmap(sqlite3_file* f, int del) { return methods_of(f)->xShmUnmap(real_of(f), del); }
int file_fetch(sqlite3_file* f, sqlite3_int64 off, int n, void** p) {
  return methods_of(f)->xFetch(real_of(f), off, n, p);
}
int file_unfetch(sqlite3_file* f, sqlite3_int64 off, void* p) {
  return methods_of(f)->xUnfetch(real_of(f), off, p);
}

// One table per version of the real file's methods, so SQLite calls only
// what the real file has.
sqlite3_io_methods methods_for(int version) {
  sqlite3_io_methods m{};
  m.iVersion = version;
  m.xClose = file_close;
  m.xRead = file_read;
  m.xWrite = file_write;
  m.xTruncate = file_truncate;
  m.xSync = file_sync;
  m.xFileSize = file_size;
  m.xLock = file_lock;
  m.xUnlock = file_unlock;
  m.xCheckReservedLock = file_check_reserved;
  m.xFileControl = file_control;
  m.xSectorSize = file_sector_size;
  m.xDeviceCharacteristics = file_device;
  if (version >= 2) {
    m.xShmMap = file_shm_map;
    m.xShmLock = file_shm_lock;
    m.xShmBarrier = file_shm_barrier;
    m.xShmUnmap = file_shm_unmap;
  }
  if (version >= 3) {
    m.xFetch = file_fetch;
    m.xUnfetch = file_unfetch;
  }
  return m;
}
const sqlite3_io_methods kMethods[3] = {methods_for(1), methods_for(2), methods_for(3)};

int vfs_open(sqlite3_vfs*, sqlite3_filename name, sqlite3_file* f, int flags, int* out_flags) {
  auto* c = reinterpret_cast<CountingFile*>(f);
  c->real = reinterpret_cast<sqlite3_file*>(c + 1);
  c->directory_pending =
      (flags & SQLITE_OPEN_CREATE) != 0 &&
      (flags & (SQLITE_OPEN_WAL | SQLITE_OPEN_MAIN_JOURNAL | SQLITE_OPEN_SUPER_JOURNAL)) != 0;
  const int rc = g_real->xOpen(g_real, name, c->real, flags, out_flags);
  // SQLite closes a file whose pMethods is set, even after a failed open.
  const sqlite3_io_methods* m = c->real->pMethods;
  f->pMethods = m ? &kMethods[(m->iVersion < 1   ? 1
                               : m->iVersion > 3 ? 3
                                                 : m->iVersion) -
                              1]
                  : nullptr;
  return rc;
}
int vfs_delete(sqlite3_vfs*, const char* name, int sync_dir) {
  return g_real->xDelete(g_real, name, sync_dir);
}
int vfs_access(sqlite3_vfs*, const char* name, int flags, int* out) {
  return g_real->xAccess(g_real, name, flags, out);
}
int vfs_full_pathname(sqlite3_vfs*, const char* name, int n, char* out) {
  return g_real->xFullPathname(g_real, name, n, out);
}
void* vfs_dl_open(sqlite3_vfs*, const char* name) { return g_real->xDlOpen(g_real, name); }
void vfs_dl_error(sqlite3_vfs*, int n, char* out) { g_real->xDlError(g_real, n, out); }
void (*vfs_dl_sym(sqlite3_vfs*, void* h, const char* sym))(void) {
  return g_real->xDlSym(g_real, h, sym);
}
void vfs_dl_close(sqlite3_vfs*, void* h) { g_real->xDlClose(g_real, h); }
int vfs_randomness(sqlite3_vfs*, int n, char* out) { return g_real->xRandomness(g_real, n, out); }
int vfs_sleep(sqlite3_vfs*, int us) { return g_real->xSleep(g_real, us); }
int vfs_current_time(sqlite3_vfs*, double* out) { return g_real->xCurrentTime(g_real, out); }
int vfs_last_error(sqlite3_vfs*, int n, char* out) { return g_real->xGetLastError(g_real, n, out); }
int vfs_current_time64(sqlite3_vfs*, sqlite3_int64* out) {
  return g_real->xCurrentTimeInt64(g_real, out);
}
int vfs_set_system_call(sqlite3_vfs*, const char* name, sqlite3_syscall_ptr p) {
  return g_real->xSetSystemCall(g_real, name, p);
}
sqlite3_syscall_ptr vfs_get_system_call(sqlite3_vfs*, const char* name) {
  return g_real->xGetSystemCall(g_real, name);
}
const char* vfs_next_system_call(sqlite3_vfs*, const char* name) {
  return g_real->xNextSystemCall(g_real, name);
}

sqlite3_vfs g_counting{};

}  // namespace

int counted_fsync(int fd) {
  g_file_syncs.fetch_add(1, std::memory_order_relaxed);
  return ::fsync(fd);
}

int counted_fdatasync(int fd) {
  g_file_syncs.fetch_add(1, std::memory_order_relaxed);
  return ::fdatasync(fd);
}

void count_store_syncs() {
  static std::once_flag once;
  std::call_once(once, [] {
    sqlite3_initialize();
    g_real = sqlite3_vfs_find(nullptr);
    if (!g_real) return;
    sqlite3_vfs& v = g_counting;
    v.iVersion = g_real->iVersion < 3 ? g_real->iVersion : 3;
    v.szOsFile = static_cast<int>(sizeof(CountingFile)) + g_real->szOsFile;
    v.mxPathname = g_real->mxPathname;
    v.zName = "locus-counting";
    v.xOpen = vfs_open;
    v.xDelete = vfs_delete;
    v.xAccess = vfs_access;
    v.xFullPathname = vfs_full_pathname;
    v.xDlOpen = g_real->xDlOpen ? vfs_dl_open : nullptr;
    v.xDlError = g_real->xDlError ? vfs_dl_error : nullptr;
    v.xDlSym = g_real->xDlSym ? vfs_dl_sym : nullptr;
    v.xDlClose = g_real->xDlClose ? vfs_dl_close : nullptr;
    v.xRandomness = vfs_randomness;
    v.xSleep = vfs_sleep;
    v.xCurrentTime = vfs_current_time;
    v.xGetLastError = vfs_last_error;
    if (v.iVersion >= 2) v.xCurrentTimeInt64 = vfs_current_time64;
    if (v.iVersion >= 3) {
      v.xSetSystemCall = vfs_set_system_call;
      v.xGetSystemCall = vfs_get_system_call;
      v.xNextSystemCall = vfs_next_system_call;
    }
    sqlite3_vfs_register(&v, /*makeDflt=*/1);
  });
}

SyncCounts sync_counts() {
  return {g_file_syncs.load(std::memory_order_relaxed),
          g_store_syncs.load(std::memory_order_relaxed)};
}

}  // namespace locus::farm

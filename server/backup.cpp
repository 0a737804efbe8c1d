#include "server/backup.h"

#include <fcntl.h>
#include <sqlite3.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <map>
#include <set>
#include <thread>
#include <tuple>

#include "common/scene/animation.h"
#include "server/band_files.h"

namespace locus::farm {
namespace {
namespace fs = std::filesystem;

// A connection, closed on scope exit.
struct Connection {
  sqlite3* db = nullptr;
  Connection() = default;
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;
  ~Connection() { sqlite3_close(db); }
};

Status open_db(const fs::path& path, int flags, const std::string& what, Connection& c) {
  const int rc = sqlite3_open_v2(path.c_str(), &c.db, flags | SQLITE_OPEN_NOMUTEX, nullptr);
  if (rc != SQLITE_OK) {
    std::string why = what;
    why.append(" ").append(path.string()).append(": cannot open: ");
    why.append(c.db ? sqlite3_errmsg(c.db) : sqlite3_errstr(rc));
    return FailedPrecondition(why);
  }
  sqlite3_busy_timeout(c.db, 5000);
  return Status::Ok();
}

// One statement with text and integer parameters; `row` sees each result row.
Status query(sqlite3* db, const std::string& sql, const std::vector<std::string>& params,
             const std::function<void(sqlite3_stmt*)>& row) {
  sqlite3_stmt* st = nullptr;
  int rc = sqlite3_prepare_v2(db, sql.c_str(), -1, &st, nullptr);
  for (size_t i = 0; rc == SQLITE_OK && i < params.size(); ++i) {
    rc = sqlite3_bind_text(st, static_cast<int>(i) + 1, params[i].c_str(), -1, SQLITE_TRANSIENT);
  }
  while (rc == SQLITE_OK || rc == SQLITE_ROW) {
    rc = sqlite3_step(st);
    if (rc == SQLITE_ROW) row(st);
  }
  sqlite3_finalize(st);
  if (rc == SQLITE_DONE) return Status::Ok();
  std::string why = "backup: ";
  why.append(sqlite3_errmsg(db)).append(" (").append(sql).append(")");
  return Internal(why);
}

std::string column_text(sqlite3_stmt* st, int col) {
  const auto* p = reinterpret_cast<const char*>(sqlite3_column_text(st, col));
  return p ? std::string(p) : std::string();
}

// The job store, page by page from a read-only connection. The connection
// holds one read transaction throughout, so every step copies the same
// snapshot (in WAL mode that blocks no writer; without it each commit of
// the coordinator would restart the copy), and the pause between steps
// leaves the disk to the coordinator.
Status copy_store(const fs::path& from, const fs::path& to, const BackupOptions& o,
                  BackupReport& report) {
  Connection src, dst;
  if (Status s = open_db(from, SQLITE_OPEN_READONLY, "the job store", src); !s.ok()) return s;
  if (Status s = open_db(to, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, "the backup", dst);
      !s.ok())
    return s;
  if (Status s = query(src.db, "BEGIN", {}, [](sqlite3_stmt*) {}); !s.ok()) return s;
  if (Status s = query(src.db, "SELECT COUNT(*) FROM sqlite_master", {}, [](sqlite3_stmt*) {});
      !s.ok())
    return s;
  sqlite3_backup* b = sqlite3_backup_init(dst.db, "main", src.db, "main");
  if (!b) return Internal(std::string("backup: cannot start: ") + sqlite3_errmsg(dst.db));
  int rc = SQLITE_OK;
  while (true) {
    rc = sqlite3_backup_step(b, o.pages_per_step);
    if (rc == SQLITE_DONE) break;
    if (rc != SQLITE_OK && rc != SQLITE_BUSY && rc != SQLITE_LOCKED) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(o.pause_ms));
  }
  report.pages = sqlite3_backup_pagecount(b);
  sqlite3_backup_finish(b);
  query(src.db, "COMMIT", {}, [](sqlite3_stmt*) {});
  if (rc != SQLITE_DONE) {
    std::string why = "backup of ";
    why.append(from.string()).append(": ").append(sqlite3_errstr(rc));
    return Internal(why);
  }
  std::string check;
  if (Status s = query(dst.db, "PRAGMA quick_check", {},
                       [&](sqlite3_stmt* st) { check += column_text(st, 0); });
      !s.ok())
    return s;
  if (check != "ok") return Internal("the backup's copy of the job store is damaged: " + check);
  return Status::Ok();
}

// Hard-linked when on the same filesystem (the coordinator replaces its
// band and frame files by rename and never writes into one, so a link is a
// snapshot), else copied. False when the file is gone.
Result<bool> take_file(const fs::path& from, const fs::path& to, BackupReport& report) {
  std::error_code ec;
  if (fs::exists(to, ec)) return true;
  fs::create_directories(to.parent_path(), ec);
  if (ec) return Internal(to.parent_path().string() + ": cannot create: " + ec.message());
  fs::create_hard_link(from, to, ec);
  if (!ec) {
    ++report.linked;
    return true;
  }
  if (ec == std::errc::no_such_file_or_directory) return false;
  fs::copy_file(from, to, ec);
  if (ec == std::errc::no_such_file_or_directory) return false;
  if (ec) return Internal(from.string() + ": cannot copy to " + to.string() + ": " + ec.message());
  ++report.copied;
  return true;
}

bool is_band_file(const fs::path& p) { return p.extension() == ".band"; }
// Frames being written (.partial-<file>) are not frames yet.
bool is_job_file(const fs::path& p) { return p.filename().string().rfind(".partial-", 0) != 0; }

// Before the store is copied, what its job directories hold: band files
// first, then the rest. A frame written meanwhile removes its band files
// only once its own file is in place and recorded, so each band accepted
// before the backup began is taken either as a band file or as part of a
// frame the copied store will name as written.
Status take_job_dir(const fs::path& from, const fs::path& to, BackupReport& report) {
  std::error_code ec;
  for (const fs::path& sub : {from / "bands", from}) {
    std::vector<fs::path> files;
    for (const auto& e : fs::directory_iterator(sub, ec)) {
      std::error_code fe;
      if (!e.is_regular_file(fe)) continue;
      const fs::path& p = e.path();
      if (sub == from ? is_job_file(p) : is_band_file(p)) files.push_back(p);
    }
    for (const fs::path& p : files) {
      auto taken = take_file(p, to / fs::relative(p, from), report);
      if (!taken.ok()) return taken.status();
    }
  }
  return Status::Ok();
}

// Whether the copied store holds a band's pixels itself: a row of some table
// keyed by (job_id, frame, band) with a non-empty BLOB in it (a value
// stored as one, or in a column declared BLOB). Schema 1 keeps pixels only
// in band files; a store that keeps them in the database needs no band
// file for them.
class PixelsInStore {
 public:
  static Result<PixelsInStore> read(sqlite3* db) {
    PixelsInStore p;
    p.db_ = db;
    std::vector<std::string> tables;
    Status s = query(db, "SELECT name FROM sqlite_master WHERE type = 'table'", {},
                     [&](sqlite3_stmt* st) { tables.push_back(column_text(st, 0)); });
    if (!s.ok()) return s;
    for (const std::string& t : tables) {
      int keys = 0;
      s = query(db,
                "SELECT COUNT(*) FROM pragma_table_info(?) WHERE name IN ('job_id', 'frame', "
                "'band')",
                {t}, [&](sqlite3_stmt* st) { keys = sqlite3_column_int(st, 0); });
      if (!s.ok()) return s;
      if (keys == 3) p.tables_.push_back(t);
    }
    return p;
  }
  Result<bool> holds(const std::string& job, int frame, int band) const {
    bool found = false;
    for (const std::string& t : tables_) {
      std::string sql = "SELECT * FROM \"";
      sql.append(t).append("\" WHERE job_id = ? AND frame = ? AND band = ?");
      Status s = query(db_, sql, {job, std::to_string(frame), std::to_string(band)},
                       [&](sqlite3_stmt* st) {
                         for (int c = 0; c < sqlite3_column_count(st); ++c) {
                           const char* declared = sqlite3_column_decltype(st, c);
                           const bool blob = sqlite3_column_type(st, c) == SQLITE_BLOB ||
                                             (declared && strcasestr(declared, "BLOB"));
                           if (blob && sqlite3_column_bytes(st, c) > 0) found = true;
                         }
                       });
      if (!s.ok()) return s;
    }
    return found;
  }

 private:
  sqlite3* db_ = nullptr;
  std::vector<std::string> tables_;
};

std::string band_name(const std::string& job, int frame, int band) {
  return "job " + job + " frame " + std::to_string(frame) + " band " + std::to_string(band);
}

// After the store is copied: every file it needs is in OUT (taken now if it
// came after the first pass), nothing else is. Problems are named in
// `problems`.
Status complete_files(const fs::path& out, const fs::path& root, BackupReport& report,
                      std::vector<std::string>& problems) {
  Connection copy;
  if (Status s = open_db(out / "locus.db", SQLITE_OPEN_READONLY, "the backup", copy); !s.ok())
    return s;
  std::map<std::string, std::string> outputs;  // job id -> frame file pattern
  Status s = query(copy.db, "SELECT id, output FROM jobs", {}, [&](sqlite3_stmt* st) {
    outputs[column_text(st, 0)] = column_text(st, 1);
  });
  if (!s.ok()) return s;
  report.jobs = static_cast<int>(outputs.size());
  auto in_store = PixelsInStore::read(copy.db);
  if (!in_store.ok()) return in_store.status();
  // Accepted bands of frames not recorded as written.
  std::set<fs::path> bands_needed;
  std::vector<std::tuple<std::string, int, int>> bands;
  s = query(copy.db,
            "SELECT b.job_id, b.frame, b.band FROM bands b WHERE b.done AND NOT EXISTS "
            "(SELECT 1 FROM frames f WHERE f.job_id = b.job_id AND f.frame = b.frame)",
            {}, [&](sqlite3_stmt* st) {
              bands.emplace_back(column_text(st, 0), sqlite3_column_int(st, 1),
                                 sqlite3_column_int(st, 2));
            });
  if (!s.ok()) return s;
  for (const auto& [job, frame, band] : bands) {
    const fs::path rel = band_file_path(job, frame, band);  // <job>/bands/<frame>-<band>.band
    auto taken = take_file(root / rel, out / "jobs" / rel, report);
    if (!taken.ok()) return taken.status();
    if (*taken) {
      bands_needed.insert(out / "jobs" / rel);
      continue;
    }
    auto held = in_store->holds(job, frame, band);
    if (!held.ok()) return held.status();
    if (*held) continue;
    // Accepted after the first pass, its frame written since: the frame's
    // file is there, the copied store does not name it yet.
    const std::string file = frame_path(outputs[job], frame);
    auto frame_taken = take_file(root / job / file, out / "jobs" / job / file, report);
    if (!frame_taken.ok()) return frame_taken.status();
    if (*frame_taken) {
      report.rendered_again.push_back(band_name(job, frame, band));
    } else {
      problems.push_back(band_name(job, frame, band) +
                         " is accepted in the store, but neither its band file " +
                         (root / rel).string() + " nor its frame's file " +
                         (root / job / file).string() + " is there");
    }
  }
  std::vector<std::pair<std::string, std::string>> frames;
  s = query(copy.db, "SELECT job_id, file FROM frames", {}, [&](sqlite3_stmt* st) {
    frames.emplace_back(column_text(st, 0), column_text(st, 1));
  });
  if (!s.ok()) return s;
  for (const auto& [job, file] : frames) {
    auto taken = take_file(root / job / file, out / "jobs" / job / file, report);
    if (!taken.ok()) return taken.status();
    if (!*taken) {
      problems.push_back("job " + job + ": " + file + " is recorded as written, but " +
                         (root / job / file).string() + " is not there");
    }
  }
  // Band files of frames written since the first pass, and directories of
  // jobs deleted since, are not the copied store's.
  std::error_code ec;
  for (const auto& j : fs::directory_iterator(out / "jobs", ec)) {
    const std::string job = j.path().filename().string();
    if (!outputs.count(job)) {
      fs::remove_all(j.path(), ec);
      continue;
    }
    for (const auto& e : fs::directory_iterator(j.path() / "bands", ec)) {
      if (!bands_needed.count(e.path())) fs::remove(e.path(), ec);
    }
    for (const auto& e : fs::directory_iterator(j.path(), ec)) {
      if (e.is_regular_file(ec)) ++report.job_files;
    }
  }
  report.band_files = static_cast<int>(bands_needed.size());
  return Status::Ok();
}

// What was written under `dir` reaches the disk (one syncfs for its
// filesystem).
Status sync_filesystem(const fs::path& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return Internal(dir.string() + ": cannot open: " + std::strerror(errno));
  const int r = ::syncfs(fd);
  ::close(fd);
  if (r != 0) return Internal(dir.string() + ": cannot sync: " + std::strerror(errno));
  return Status::Ok();
}

Status backup_into(const BackupOptions& o, const fs::path& temp, BackupReport& report) {
  const fs::path data(o.data_dir);
  const fs::path root = o.output_root.empty() ? data / "jobs" : fs::path(o.output_root);
  const fs::path db = data / "locus.db";
  std::error_code ec;
  if (!fs::is_regular_file(db, ec))
    return FailedPrecondition("--data " + o.data_dir + " holds no job store (locus.db)");
  // The jobs as they are now; their directories before the store.
  std::vector<std::string> jobs;
  {
    Connection src;
    if (Status s = open_db(db, SQLITE_OPEN_READONLY, "the job store", src); !s.ok()) return s;
    Status s = query(src.db, "SELECT id FROM jobs", {},
                     [&](sqlite3_stmt* st) { jobs.push_back(column_text(st, 0)); });
    if (!s.ok()) return s;
  }
  for (const std::string& job : jobs) {
    if (Status s = take_job_dir(root / job, temp / "jobs" / job, report); !s.ok()) return s;
  }
  if (Status s = copy_store(db, temp / "locus.db", o, report); !s.ok()) return s;
  std::vector<std::string> problems;
  if (Status s = complete_files(temp, root, report, problems); !s.ok()) return s;
  if (!problems.empty()) {
    std::string why = "the data directory is inconsistent (no backup written): ";
    for (size_t i = 0; i < problems.size(); ++i) why.append(i ? "; " : "").append(problems[i]);
    return FailedPrecondition(why);
  }
  return sync_filesystem(temp);
}

}  // namespace

Result<BackupReport> backup_data_dir(const BackupOptions& o) {
  const fs::path out = fs::absolute(o.out);
  std::error_code ec;
  if (fs::exists(out, ec))
    return FailedPrecondition("backup: " + o.out + " exists; give a new directory");
  if (!fs::is_directory(out.parent_path(), ec))
    return FailedPrecondition("backup: " + out.parent_path().string() + " is not a directory");
  std::string name = ".";
  name.append(out.filename().string()).append(".partial-XXXXXX");
  std::string temp = (out.parent_path() / name).string();
  if (!mkdtemp(temp.data()))
    return Internal("backup: cannot create a directory beside " + o.out + ": " +
                    std::strerror(errno));
  BackupReport report;
  Status s = backup_into(o, temp, report);
  // Complete, or not there at all.
  if (s.ok() && ::renameat2(AT_FDCWD, temp.c_str(), AT_FDCWD, out.c_str(), RENAME_NOREPLACE) != 0)
    s = Internal("backup: cannot rename " + temp + " to " + o.out + ": " + std::strerror(errno));
  if (!s.ok()) {
    fs::remove_all(temp, ec);
    return s;
  }
  if (Status synced = sync_filesystem(out.parent_path()); !synced.ok()) return synced;
  return report;
}

}  // namespace locus::farm

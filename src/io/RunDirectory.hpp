#pragma once
// A run directory written as a transaction (docs/usage.md, "What ehlsim
// guarantees about its outputs"): a reader of DIR sees the earlier complete
// run or the new complete run, never a mix and never a partial one.
//
//   DIR/                  the last complete run (replaced as a whole)
//   .DIR.lock             flock(2) of the run that writes DIR (pid, host,
//                         start time inside); released when the process dies
//   .DIR.part-<pid>/      the new run while it is written (staging)
//   DIR.checkpoint.nc     the checkpoint of the run in progress: kept when it
//                         fails or is interrupted, for --restart; removed when
//                         a run into DIR completes
//
// publish() fsyncs the staging directory and swaps it with DIR atomically
// (renameat2 RENAME_EXCHANGE; a plain rename when DIR does not exist), then
// removes the earlier run.  A RunDirectory destroyed unpublished removes its
// staging directory.  Debris of a killed run (staging, swapped-out old runs)
// is removed by the next run into DIR, which holds the lock.
//
// A new run replaces DIR as a whole.  An amendment (`ehlsim spike`, which
// rewrites its three files in a run directory) replaces only some files: just
// before the swap the staging directory gets hard links of everything else in
// DIR, so the same swap publishes the new files together and nothing else
// changes.
//
// A DIR that is a symbolic link stays one: DIR above is then the directory it
// points to (created when missing), which the run replaces or amends.
#include <sys/types.h>

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "config/ParameterSet.hpp"

namespace ehlsim {

/// An exclusive lock on a target path, held until destruction or the death
/// of the process: "<parent>/.<name>.lock".
class PathLock {
 public:
  /// Throws ConfigError naming the holder (pid, host, start time) when
  /// another process holds the lock, std::runtime_error when the lock file
  /// cannot be created.  `target` as resolve_run_directory gives it, `shown`
  /// as the user named it.
  PathLock(const std::filesystem::path& target, const std::filesystem::path& shown);
  ~PathLock();
  PathLock(const PathLock&) = delete;
  PathLock& operator=(const PathLock&) = delete;

  [[nodiscard]] const std::filesystem::path& path() const { return path_; }
  /// Removes the lock file and unlocks now (the destructor's work), freeing
  /// its file descriptor.
  void release() noexcept;

 private:
  std::filesystem::path path_;
  int fd_ = -1;
};

/// An entry below a directory, by its relative path and its inode: what an
/// amendment carries over, and how it notices a change of DIR meanwhile.
struct CarriedEntry {
  std::filesystem::path relative;
  dev_t device = 0;
  ino_t inode = 0;
  friend bool operator==(const CarriedEntry&, const CarriedEntry&) = default;
};

/// What tells a file from one put in its place or written over: its inode,
/// size and modification time (all zero: no file).
struct FileStamp {
  dev_t device = 0;
  ino_t inode = 0;
  off_t size = 0;
  std::int64_t modified_ns = 0;
  friend bool operator==(const FileStamp&, const FileStamp&) = default;
};

class RunDirectory {
 public:
  /// The names (in DIR itself) that an amendment writes anew.
  struct Amend {
    std::vector<std::string> replaced;
  };

  /// A new run: locks `target`, checks that it is missing, empty or an earlier
  /// ehlsim run (else ConfigError naming the first foreign file), removes the
  /// debris of killed runs and creates a fresh staging directory.
  explicit RunDirectory(const std::filesystem::path& target);
  /// An amendment of `target` (missing, or a directory: else ConfigError):
  /// locks it, removes the debris of killed runs and creates a fresh staging
  /// directory for the files named in `amend.replaced`.  publish() adds every
  /// other entry of `target` as a hard link (a copy where links fail) and
  /// throws std::runtime_error when one cannot be carried over.
  RunDirectory(const std::filesystem::path& target, const Amend& amend);
  ~RunDirectory();
  RunDirectory(const RunDirectory&) = delete;
  RunDirectory& operator=(const RunDirectory&) = delete;

  /// DIR as the user named it (for messages).
  [[nodiscard]] const std::filesystem::path& target() const { return target_; }
  /// Where the files of the new run are written.
  [[nodiscard]] const std::filesystem::path& staging() const { return staging_; }
  /// DIR.checkpoint.nc: where the checkpoints of the run in progress are
  /// kept, for a restart (beside the directory a symbolic link DIR points to).
  [[nodiscard]] std::filesystem::path checkpoint() const;
  /// The run's last checkpoint, in the staging directory: published as
  /// DIR/checkpoint.nc.  Each checkpoint written as checkpoint() is copied
  /// here at once (stage_checkpoint), so that what the run publishes is what
  /// it wrote, whatever becomes of checkpoint() meanwhile (another case's
  /// checkpoint put there, by a rename or written over it, was published as
  /// the run's own with exit 0; one removed failed the finished run).
  [[nodiscard]] std::filesystem::path staged_checkpoint() const;
  /// Copies checkpoint(), just written, to staged_checkpoint() and notes
  /// checkpoint()'s identity.  Throws std::runtime_error naming the file.
  void stage_checkpoint();
  /// For a run that writes checkpoints: ConfigError when checkpoint() or its
  /// partial file is not ehlsim's: a symbolic link (a dangling one was
  /// replaced, then deleted), a directory, or a file that is no NetCDF-4 one
  /// (a partial file may be empty: a run killed as it began one).  The user's
  /// file there was overwritten.
  void refuse_foreign_checkpoint() const;

  /// Makes the staged run DIR, with staged_checkpoint() as DIR/checkpoint.nc
  /// when there is one.  checkpoint() is removed when it is still the run's
  /// own, or when the run completed the state it resumed from it
  /// (`resumed_from_checkpoint`) and it is still that file; else it is left
  /// as it is.  Throws std::runtime_error when a file cannot be synced or
  /// renamed, or when DIR changed meanwhile (a foreign file in it, an entry of
  /// an amended DIR added, removed or replaced, a mount in it or in the
  /// staging directory); PublishInterrupted when SIGINT, SIGTERM or SIGHUP
  /// came before the swap (io/Interrupt.hpp).  DIR then still holds the
  /// earlier run.  The swap is the commit point: a signal after it does not
  /// undo the published run.
  void publish(bool resumed_from_checkpoint = false);
  [[nodiscard]] bool published() const { return published_; }

 private:
  std::filesystem::path target_;     ///< as given
  std::filesystem::path directory_;  ///< as given, a symbolic link followed
  std::filesystem::path resolved_;   ///< absolute, symlinks of the parents resolved
  PathLock lock_;
  std::filesystem::path staging_;
  bool amend_ = false;
  std::vector<std::string> replaced_;           ///< amendment: the names written anew
  std::vector<CarriedEntry> carried_;           ///< amendment: what was carried over from DIR
  std::vector<CarriedEntry> entries_at_start_;  ///< new run: what DIR held when it began
  bool published_ = false;
  /// checkpoint() when the run began, and as the run last wrote it, for publish.
  FileStamp checkpoint_at_start_;
  FileStamp checkpoint_written_;

  /// Throws std::runtime_error when something was mounted in the staging directory.
  void refuse_mount_in_staging() const;
  /// Throws std::runtime_error when DIR may no longer be replaced by the staging directory.
  void check_target_unchanged() const;
};

/// Removes `path` and what lies below it, but nothing where a file system
/// (or a bind mount) is mounted, nor the directories that lead there: a
/// tmpfs mounted in a killed run's leftover staging directory was emptied by
/// the next run.  Errors are ignored (what stays is a later run's debris).
void remove_within_mount(const std::filesystem::path& path) noexcept;

/// Puts the complete directory `staging` in the place of `target` (missing
/// or a directory) in one atomic step, as publish() does, and removes what
/// `target` held: a reader sees the earlier contents or the new ones.
/// Both must be on one file system; the caller holds a lock on `target`.
/// Throws std::runtime_error when a file cannot be synced or renamed.
void replace_directory(const std::filesystem::path& staging, const std::filesystem::path& target);

/// `target` absolute, without a trailing separator, with the symbolic links of
/// its parent resolved (one spelling per directory, for the lock); creates
/// the parent.  Throws ConfigError for "" or a path without a name, or below a
/// file or a loop of symbolic links; std::runtime_error when the parent
/// cannot be created otherwise.
[[nodiscard]] std::filesystem::path resolve_run_directory(const std::filesystem::path& target);

/// The ConfigError of an --out `shown` that runs into a loop of symbolic
/// links (in its final name or in a parent).
[[nodiscard]] ConfigError link_loop_error(const std::filesystem::path& shown);

/// `shown` itself, after a ConfigError (--out) if it exists and is not a
/// directory.  Checked before the lock: the lock file beside a file the user
/// cannot write next to (`--out /etc/hostname`) failed to be created first,
/// and the run ended with exit 1 for what is bad input.
const std::filesystem::path& refuse_non_directory(const std::filesystem::path& shown);

/// The start of the names of the staging directories of `name` (".NAME.part-"),
/// before the writer's process id: also for a directory that ehlsim stages
/// without a RunDirectory (a study's figures).
[[nodiscard]] std::string staging_prefix(std::string_view name);

/// The run directory whose staging directory `dir` is (".NAME.part-PID",
/// symbolic links resolved: NAME beside it), or none when it is not one.
/// Such a directory is a run being written, or what a killed run left.
[[nodiscard]] std::optional<std::filesystem::path> run_directory_staged_in(
    const std::filesystem::path& dir);

/// Whether `inside` is the directory `dir` or lies below it (both existing;
/// symbolic links resolved).  False when either cannot be resolved.
[[nodiscard]] bool holds_path(const std::filesystem::path& dir,
                              const std::filesystem::path& inside);

/// Throws ConfigError unless `dir` is missing, an empty directory, or an
/// earlier ehlsim run: an ehlsim run.json and nothing but files ehlsim writes
/// (the run's, `ehlsim spike`'s and their ".part" names, also in
/// subdirectories).
void check_replaceable_run_directory(const std::filesystem::path& dir);

/// Throws ConfigError when `dir` is a mount point or holds one: replacing
/// it failed with EBUSY after all the work, or moved the mounts away with
/// the earlier directory (also done by check_replaceable_run_directory).
void check_no_mount_point(const std::filesystem::path& dir);

}  // namespace ehlsim

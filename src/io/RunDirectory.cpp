#include "io/RunDirectory.hpp"

#include <dirent.h>
#include <fcntl.h>
#include <fmt/chrono.h>
#include <fmt/format.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <climits>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <system_error>

#include "config/Parameters.hpp"
#include "config/SystemFailure.hpp"
#include "io/AtomicFile.hpp"
#include "io/Checkpoint.hpp"
#include "io/Interrupt.hpp"
#include "io/NetcdfStatus.hpp"
#include "io/RunAnalysis.hpp"

namespace ehlsim {

namespace fs = std::filesystem;

namespace {

constexpr std::string_view kLockSuffix = ".lock";
constexpr std::string_view kStagingInfix = ".part-";
/// The permission bits of a mode (with set-user-ID, set-group-ID and sticky).
constexpr mode_t kPermissionBits = 07777;
constexpr std::string_view kOldInfix = ".old-";
constexpr std::string_view kCheckpointSuffix = ".checkpoint.nc";
/// gethostname's buffer: Linux's HOST_NAME_MAX is 64, POSIX allows up to 255.
constexpr std::size_t kHostNameLength = 256;
/// The lock file's text is lock_holder_text(): a pid, the host name and a
/// time, at most about 120 characters with a host name of 64.
constexpr std::size_t kLockTextLength = 512;
/// Digits of a process id: Linux's pid_max is at most 2^22 (7 digits).
constexpr std::size_t kLongestPidDigits = 7;
/// Links followed from --out before a chain counts as a loop (Linux's own limit, ELOOP).
constexpr int kMaxLinkHops = 40;

/// Every file name ehlsim writes into a run directory (impact, spike,
/// rolling), and the figure that scripts/plot_rolling.py puts beside a
/// rolling run's files by default: made from the run, it goes with it.
const std::set<std::string, std::less<>>& ehlsim_file_names() {
  static const std::set<std::string, std::less<>> names = {
      "timeseries.csv", "spike.csv",         "fields.nc",        "run.json",
      "checkpoint.nc",  kSpikeSnapshotsFile, kSpikeProfilesFile, kAxisProfilesFile,
      "profile_x.csv",  "profile_y.csv",     "convergence.csv",  "rolling.png"};
  return names;
}

/// The name PathLock gives the lock beside a target: ".NAME.lock".
bool is_lock_file_name(std::string_view name) {
  return name.starts_with('.') && name.ends_with(kLockSuffix);
}

bool is_ehlsim_file_name(std::string name) {
  // The lock of an ehlsim writer into a subdirectory (`ehlsim spike RUN --out
  // RUN/gauss`), left behind when it was killed, or held while it runs.
  if (is_lock_file_name(name)) return true;
  const std::string_view part = PartialFile::kSuffix;
  if (name.size() > part.size() && name.ends_with(part)) name.resize(name.size() - part.size());
  return ehlsim_file_names().contains(name);
}

std::string system_message(int error) { return std::generic_category().message(error); }

/// DIR without a trailing separator ("run/" -> "run").
fs::path without_trailing_separator(fs::path path) {
  if (!path.empty() && path.filename().empty()) path = path.parent_path();
  return path;
}

/// `target` itself, or the path a symbolic link `target` points to (a chain
/// followed to its end, which may be missing): the directory a run into
/// `target` writes, so that the swap replaces that directory, not the link.
/// Relative links are taken from the link's directory.  ConfigError for a loop.
fs::path follow_final_link(const fs::path& target) {
  fs::path path = without_trailing_separator(target);
  for (int hops = 0;; ++hops) {
    std::error_code ec;
    if (!fs::is_symlink(fs::symlink_status(path, ec))) return path;
    if (hops == kMaxLinkHops) {
      throw link_loop_error(target);
    }
    const fs::path link = fs::read_symlink(path);
    // From the link's real directory, resolved as the kernel does: "runs/latest"
    // -> "../mine", with runs a link to data/runs, is data/mine, not mine
    // (a lexical "runs/../mine" replaced the user's ./mine).
    const fs::path next = without_trailing_separator(
        link.is_absolute() ? link : fs::weakly_canonical(fs::absolute(path).parent_path()) / link);
    const fs::path name = next.filename();
    path = name == "." || name == ".." ? fs::weakly_canonical(next)
                                       : fs::weakly_canonical(next.parent_path()) / name;
  }
}

/// A sibling of `target`: "<parent>/<prefix><name><suffix>".
fs::path sibling(const fs::path& target, std::string_view prefix, std::string_view suffix) {
  return target.parent_path() / fmt::format("{}{}{}", prefix, target.filename().string(), suffix);
}

bool is_ehlsim_run_json(const fs::path& path) {
  std::ifstream in(path);
  if (!in) return false;
  const nlohmann::json run = nlohmann::json::parse(in, nullptr, false);
  return !run.is_discarded() && run.is_object() && run.contains("program") &&
         run["program"].is_object() && run["program"].value("name", "") == "ehlsim";
}

/// True for a file that ehlsim writes into a subdirectory of a run: a
/// file of a run there (beside an ehlsim run.json), one of `ehlsim spike RUN
/// --out RUN/DIR` (a spike analysis file), or a lock or partial file.  A file
/// of the user's that bears a run's name elsewhere (RUN/a/b/fields.nc) is not.
bool is_ehlsim_file_below(const fs::path& file) {
  const std::string name = file.filename().string();
  if (!is_ehlsim_file_name(name)) return false;
  if (is_lock_file_name(name) || is_ehlsim_run_json(file.parent_path() / "run.json")) return true;
  const std::string_view part = PartialFile::kSuffix;
  if (name.ends_with(part)) return true;
  return name == kSpikeSnapshotsFile || name == kSpikeProfilesFile || name == kAxisProfilesFile;
}

/// True for a lock file as PathLock writes it: "pid N on host H, started
/// ...", or empty (its writer killed before it wrote that).  A user's
/// ".notes.lock" in a run directory was deleted with it.
bool is_ehlsim_lock(const fs::path& file) {
  std::ifstream in(file);
  std::string text;
  std::getline(in, text);
  std::error_code ec;
  if (text.empty()) return fs::file_size(file, ec) == 0 && !ec;
  constexpr std::string_view kHolder = "pid ";  // lock_holder_text
  return text.starts_with(kHolder) && text.size() > kHolder.size() &&
         std::isdigit(static_cast<unsigned char>(text[kHolder.size()])) != 0;
}

/// The first entry below `dir` that is not a file ehlsim writes ("" if none).
/// An empty directory is the user's: ehlsim makes none in a run.
fs::path first_foreign_entry(const fs::path& dir) {
  for (auto it = fs::recursive_directory_iterator(dir); it != fs::recursive_directory_iterator();
       ++it) {
    if (it->is_symlink()) return it->path();
    if (it->is_directory()) {
      if (fs::is_empty(it->path())) return it->path();
      continue;
    }
    const std::string name = it->path().filename().string();
    const bool ehlsims =
        it.depth() == 0 ? is_ehlsim_file_name(name) : is_ehlsim_file_below(it->path());
    if (!it->is_regular_file() || !ehlsims) return it->path();
    if (is_lock_file_name(name) && !is_ehlsim_lock(it->path())) return it->path();
  }
  return {};
}

/// The first lock below `dir` that an ehlsim run holds now (`ehlsim spike
/// RUN --out RUN/gauss` while RUN would be replaced), or "".  A lock left by
/// a killed run is free: flock(2) locks die with their process.
fs::path first_held_lock(const fs::path& dir) {
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::end(it);
       it.increment(ec)) {
    if (!it->is_regular_file(ec) || !is_lock_file_name(it->path().filename().string())) continue;
    const int fd = ::open(it->path().c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) continue;
    const bool held = ::flock(fd, LOCK_SH | LOCK_NB) != 0 && errno == EWOULDBLOCK;
    ::close(fd);
    if (held) return it->path();
  }
  return {};
}

std::string lock_holder_text() {
  std::array<char, kHostNameLength> host{};
  if (gethostname(host.data(), host.size() - 1) != 0) std::strcpy(host.data(), "unknown");
  const auto now = std::chrono::system_clock::now();
  return fmt::format("pid {} on host {}, started {:%Y-%m-%d %H:%M:%S} UTC", getpid(), host.data(),
                     fmt::gmtime(std::chrono::system_clock::to_time_t(now)));
}

std::string read_lock_holder(int fd) {
  std::array<char, kLockTextLength> text{};
  const ssize_t n = pread(fd, text.data(), text.size() - 1, 0);
  return n > 0 ? std::string(text.data(), static_cast<std::size_t>(n)) : std::string("starting");
}

/// Whether `digits` is a process id as written into the names beside DIR.
bool is_process_id_text(std::string_view digits) {
  return !digits.empty() && digits.size() <= kLongestPidDigits &&
         digits.find_first_not_of("0123456789") == std::string_view::npos;
}

/// True when `name` is "<prefix>PID" for the id of a process that has ended:
/// what a killed writer left.  A live process's ("<prefix>1"), or a name
/// that is no process id ("<prefix>mydata"), is the user's, and stays.
bool left_by_ended_process(std::string_view name, std::string_view prefix) {
  if (!name.starts_with(prefix)) return false;
  const std::string_view digits = name.substr(prefix.size());
  if (!is_process_id_text(digits)) return false;
  const pid_t pid = static_cast<pid_t>(std::stol(std::string(digits)));
  return pid > 0 && ::kill(pid, 0) != 0 && errno == ESRCH;
}

/// The staging directories and swapped-out runs that killed runs into `target` left.
void remove_debris(const fs::path& target) {
  const std::string staging = staging_prefix(target.filename().string());
  const std::string old = fmt::format(".{}{}", target.filename().string(), kOldInfix);
  std::error_code ec;
  for (const fs::directory_entry& entry : fs::directory_iterator(target.parent_path(), ec)) {
    const std::string name = entry.path().filename().string();
    if (left_by_ended_process(name, staging) || left_by_ended_process(name, old))
      remove_within_mount(entry.path());
  }
}

/// Copies the file `from` over `to`, with its permissions, and syncs it.
/// Throws std::runtime_error naming both and the reason
/// (std::filesystem::copy_file said "Input/output error" of a full disk).
void copy_contents(const fs::path& from, const fs::path& to) {
  const auto fail = [&](int error) {
    throw std::runtime_error(fmt::format("cannot copy '{}' to '{}': {}", from.string(), to.string(),
                                         system_message(error)));
  };
  const int in = ::open(from.c_str(), O_RDONLY | O_CLOEXEC);
  if (in < 0) fail(errno);
  struct stat source {};
  if (::fstat(in, &source) != 0) {
    const int error = errno;
    ::close(in);
    fail(error);
  }
  const int out = ::open(to.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC,
                         source.st_mode & kPermissionBits);
  if (out < 0) {
    const int error = errno;
    ::close(in);
    fail(error);
  }
  int error = ::fchmod(out, source.st_mode & kPermissionBits) == 0 ? 0 : errno;  // umask aside
  constexpr std::size_t kChunk = 1 << 20;
  std::vector<char> buffer(kChunk);
  while (error == 0) {
    const ssize_t got = ::read(in, buffer.data(), buffer.size());
    if (got < 0 && errno == EINTR) continue;  // a signal the run acts on after the step
    if (got <= 0) {
      error = got < 0 ? errno : 0;
      break;
    }
    for (ssize_t done = 0; done < got && error == 0;) {
      const ssize_t put = ::write(out, buffer.data() + done, static_cast<std::size_t>(got - done));
      if (put < 0 && errno == EINTR) continue;
      if (put <= 0)
        error = put < 0 ? errno : EIO;
      else
        done += put;
    }
  }
  if (error == 0 && ::fsync(out) != 0) error = errno;
  ::close(in);
  if (::close(out) != 0 && error == 0) error = errno;
  if (error != 0) fail(error);
}

/// `to` as another name of the regular file `from`, or a copy of it where no
/// link can be made.
void link_or_copy(const fs::path& from, const fs::path& to) {
  if (link(from.c_str(), to.c_str()) == 0) return;
  copy_contents(from, to);
}

/// The stamp of the file `path` (links not followed); all zero when there is none.
FileStamp stamp_of(const fs::path& path) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0) return {};
  constexpr std::int64_t kNanosecondsPerSecond = 1'000'000'000;
  return {
      st.st_dev, st.st_ino, st.st_size,
      static_cast<std::int64_t>(st.st_mtim.tv_sec) * kNanosecondsPerSecond + st.st_mtim.tv_nsec};
}

/// Whether `name` in the directory `dir_fd` (a directory, or a file) is where
/// another file system, or a bind mount of this one (the same st_dev: only
/// statx tells), is mounted.
bool is_mount_point_at(int dir_fd, const char* name, dev_t device_above) {
  struct statx st {};
  if (statx(dir_fd, name, AT_SYMLINK_NOFOLLOW, STATX_BASIC_STATS, &st) != 0) return false;
  if (makedev(st.stx_dev_major, st.stx_dev_minor) != device_above) return true;
  return (st.stx_attributes_mask & STATX_ATTR_MOUNT_ROOT) != 0 &&
         (st.stx_attributes & STATX_ATTR_MOUNT_ROOT) != 0;
}

/// The same for `path`.
bool is_mount_point(const fs::path& path, dev_t device_above) {
  return is_mount_point_at(AT_FDCWD, path.c_str(), device_above);
}

/// The device of the directory that holds `path`.
dev_t device_of_parent(const fs::path& path) {
  struct stat parent {};
  const fs::path above = path.has_parent_path() ? path.parent_path() : fs::path(".");
  return ::stat(above.c_str(), &parent) == 0 ? parent.st_dev : 0;
}

/// How deep remove_entries_within_mount descends, one open descriptor per
/// level: a tree deeper than this keeps what lies below it.
constexpr int kMaxRemovalDepth = 256;

/// The names in the open directory `dir`, but "." and "..".
std::vector<std::string> names_in(DIR* dir) {
  std::vector<std::string> names;
  while (const dirent* entry = ::readdir(dir)) {
    const std::string_view name = entry->d_name;
    if (name != "." && name != "..") names.emplace_back(name);
  }
  return names;
}

/// remove_within_mount below the directory `dir_fd`, on the device `device`;
/// closes `dir_fd`.  Relative to descriptors, not paths: a leftover tree
/// deeper than PATH_MAX (lstat of its full paths said "File name too long")
/// goes as well.  One descriptor per level, none more: out of descriptors
/// (ulimit -n), a second one for the listing failed, and the staging
/// directory stayed.
void remove_entries_within_mount(int dir_fd, dev_t device, int depth) noexcept {
  DIR* dir = ::fdopendir(dir_fd);
  if (dir == nullptr) {
    ::close(dir_fd);
    return;
  }
  const int at = ::dirfd(dir);
  for (const std::string& name : names_in(dir)) {
    struct stat st {};
    if (::fstatat(at, name.c_str(), &st, AT_SYMLINK_NOFOLLOW) != 0) continue;
    if (!S_ISLNK(st.st_mode) && is_mount_point_at(at, name.c_str(), device))
      continue;  // and its parents stay
    if (!S_ISDIR(st.st_mode)) {
      ::unlinkat(at, name.c_str(), 0);
      continue;
    }
    if (depth >= kMaxRemovalDepth) continue;
    const int child = ::openat(at, name.c_str(), O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
    if (child < 0) continue;
    remove_entries_within_mount(child, device, depth + 1);
    ::unlinkat(at, name.c_str(), AT_REMOVEDIR);
  }
  ::closedir(dir);
}
}  // namespace

void remove_within_mount(const fs::path& path) noexcept {
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0) return;
  if (!S_ISDIR(st.st_mode)) {  // a file, a link (not followed), ...
    if (!is_mount_point(path, device_of_parent(path))) ::unlink(path.c_str());
    return;
  }
  if (is_mount_point(path, device_of_parent(path))) return;
  const int dir = ::open(path.c_str(), O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
  if (dir < 0) return;
  remove_entries_within_mount(dir, st.st_dev, 0);  // closes dir
  ::rmdir(path.c_str());
}

namespace {
/// The first entry below `dir` where a file system or a file is mounted, or empty.
/// Replacing `dir` would move the mount along with the earlier directory,
/// and removing that removed the mounted files: `ehlsim spike` emptied a
/// tmpfs mounted at DIR/data (and left its copy in DIR).
fs::path first_mount_point_below(const fs::path& dir) {
  struct stat top {};
  if (::stat(dir.c_str(), &top) != 0) return {};
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(dir, ec);
       !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    if (!it->is_symlink(ec) && is_mount_point(it->path(), top.st_dev)) return it->path();
  }
  return {};
}

/// The message of a mount point below the directory `shown` a run replaces.
std::string mount_point_text(const fs::path& shown, const fs::path& mount) {
  return fmt::format(
      "--out '{}' holds '{}', a mount point: ehlsim replaces the "
      "directory as a whole and cannot carry a mount over; unmount it, or choose "
      "another --out",
      shown.string(), mount.string());
}

/// Refuses (bad input) a run into `resolved`, shown as `shown`, that is or
/// holds a mount point.  One that is failed with EBUSY at the swap, after
/// all the work.
void refuse_mount_points(const fs::path& resolved, const fs::path& shown) {
  std::error_code ec;
  if (fs::is_directory(fs::symlink_status(resolved, ec)) &&
      is_mount_point(resolved, device_of_parent(resolved)))
    throw ConfigError(fmt::format("--out '{}' is a mount point: ehlsim replaces the directory as a "
                                  "whole, which a mount point cannot be; unmount it, or choose "
                                  "another --out, such as a directory in it",
                                  shown.string()),
                      "--out");
  if (const fs::path mount = first_mount_point_below(resolved); !mount.empty())
    throw ConfigError(mount_point_text(shown, shown / mount.lexically_relative(resolved)), "--out");
}

/// Every entry below `dir` (links not followed) but the `skipped` names in
/// `dir` itself, parents before their children; none when `dir` is missing.
/// A mount point below it fails, named below `shown`, the directory as the
/// user gave it.
std::vector<CarriedEntry> entries_below(const fs::path& dir,
                                        const std::vector<std::string>& skipped,
                                        const fs::path& shown) {
  std::vector<CarriedEntry> entries;
  struct stat top {};
  if (::stat(dir.c_str(), &top) != 0) return entries;
  for (auto it = fs::recursive_directory_iterator(dir); it != fs::recursive_directory_iterator();
       ++it) {
    const std::string name = it->path().filename().string();
    if (it.depth() == 0 && std::find(skipped.begin(), skipped.end(), name) != skipped.end()) {
      it.disable_recursion_pending();
      continue;
    }
    struct stat status {};
    if (lstat(it->path().c_str(), &status) != 0) {
      throw std::runtime_error(
          fmt::format("cannot read '{}': {}", it->path().string(), system_message(errno)));
    }
    if (!S_ISLNK(status.st_mode) && is_mount_point(it->path(), top.st_dev))
      throw std::runtime_error(mount_point_text(shown, shown / it->path().lexically_relative(dir)));
    entries.push_back({it->path().lexically_relative(dir), status.st_dev, status.st_ino});
  }
  std::sort(entries.begin(), entries.end(),
            [](const CarriedEntry& a, const CarriedEntry& b) { return a.relative < b.relative; });
  return entries;
}

/// stat() of `source`; throws std::runtime_error naming it when that fails.
struct stat attributes_of(const fs::path& source) {
  struct stat st {};
  if (::stat(source.c_str(), &st) != 0) {
    throw std::runtime_error(fmt::format("cannot read the attributes of '{}': {}", source.string(),
                                         system_message(errno)));
  }
  return st;
}

/// Gives `copy` the permission bits of the stat() result `source`.
void set_permission_bits(const fs::path& copy, const struct stat& source) {
  fs::permissions(copy, static_cast<fs::perms>(source.st_mode & kPermissionBits));
}

/// Gives the directory `copy` the permission bits of the directory `source`.
void copy_directory_mode(const fs::path& source, const fs::path& copy) {
  set_permission_bits(copy, attributes_of(source));
}

/// Gives `copy` the mode, owner and times of the directory `source`: an
/// amended run directory (and each directory in it) is made anew, and a
/// private one (700) came out world-readable (755), owned by whoever ran
/// ehlsim spike.  The owner is kept where this user may set it (root).
void copy_directory_attributes(const fs::path& source, const fs::path& copy) {
  const struct stat st = attributes_of(source);
  if (::chown(copy.c_str(), st.st_uid, st.st_gid) != 0 && errno != EPERM) {
    throw std::runtime_error(
        fmt::format("cannot set the owner of '{}': {}", copy.string(), system_message(errno)));
  }
  set_permission_bits(copy, st);
  const std::array<timespec, 2> times = {st.st_atim, st.st_mtim};
  ::utimensat(AT_FDCWD, copy.c_str(), times.data(), 0);  // the times are a courtesy
}

/// Whether an amendment can carry an entry of this type over: a file (as a
/// link, or a copy), a directory (made anew) or a symbolic link (copied).
bool is_carriable(const fs::file_status& status) {
  return fs::is_regular_file(status) || fs::is_directory(status) || fs::is_symlink(status);
}

/// What an entry that is_carriable refuses is, for a message.
std::string_view uncarriable_kind(const fs::file_status& status) {
  switch (status.type()) {
    case fs::file_type::fifo:
      return "a FIFO (named pipe)";
    case fs::file_type::socket:
      return "a socket";
    case fs::file_type::block:
    case fs::file_type::character:
      return "a device file";
    default:
      return "neither a file, a directory nor a symbolic link";
  }
}

/// Refuses (bad input) an amendment of `resolved`, shown as `shown`, that
/// holds an entry besides the `replaced` names that it cannot carry over:
/// `ehlsim spike` analysed the whole run and only then failed with exit 1
/// ("cannot carry '.../pipe' over").
void refuse_uncarriable_entries(const fs::path& resolved, const std::vector<std::string>& replaced,
                                const fs::path& shown) {
  for (const CarriedEntry& entry : entries_below(resolved, replaced, shown)) {
    std::error_code ec;
    const fs::file_status status = fs::symlink_status(resolved / entry.relative, ec);
    if (ec || is_carriable(status)) continue;
    throw ConfigError(
        fmt::format("--out '{}' holds '{}', {}: ehlsim makes the directory anew with "
                    "links of the entries it does not write, and can carry over only "
                    "files, directories and symbolic links; move it, or choose "
                    "another --out",
                    shown.string(), (shown / entry.relative).string(), uncarriable_kind(status)),
        "--out");
  }
}

/// Recreates `entries` of `from` in the empty directory `to`: directories
/// made anew with their attributes, files hard-linked (copied where that
/// fails), symbolic links copied; synced to disk.
void carry_over(const fs::path& from, const fs::path& to,
                const std::vector<CarriedEntry>& entries) {
  std::vector<std::pair<fs::path, fs::path>> directories;
  for (const CarriedEntry& entry : entries) {
    const fs::path source = from / entry.relative;
    const fs::path copy = to / entry.relative;
    const fs::file_status status = fs::symlink_status(source);
    if (fs::is_directory(status)) {
      fs::create_directory(copy);
      directories.emplace_back(source, copy);
    } else if (fs::is_symlink(status)) {
      fs::copy_symlink(source, copy);
    } else if (fs::is_regular_file(status)) {
      link_or_copy(source, copy);
    } else {  // one that came during the analysis (refuse_uncarriable_entries)
      throw std::runtime_error(
          fmt::format("cannot carry '{}' over: {}", source.string(), uncarriable_kind(status)));
    }
  }
  // Deepest first: a directory's times change when entries are made in it.
  for (auto it = directories.rbegin(); it != directories.rend(); ++it) {
    copy_directory_attributes(it->first, it->second);
    sync_path(it->second);
  }
}

/// A run directory's name must leave room for the names ehlsim gives the
/// files beside it (".NAME.part-PID", ".NAME.old-PID", ".NAME.lock",
/// "NAME.checkpoint.nc" and its partial file) within NAME_MAX bytes (255 on
/// Linux's file systems): else a legal name fails there with ENAMETOOLONG.
void check_name_leaves_room(const fs::path& absolute, const fs::path& shown) {
  const std::size_t extra = std::max(
      {1 + kStagingInfix.size() + kLongestPidDigits, 1 + kOldInfix.size() + kLongestPidDigits,
       1 + kLockSuffix.size(), kCheckpointSuffix.size() + std::strlen(PartialFile::kSuffix)});
  const std::size_t length = absolute.filename().string().size();
  if (length + extra <= NAME_MAX) return;
  throw ConfigError(fmt::format("--out '{}': a name of {} bytes is too long: ehlsim writes "
                                "'.NAME.part-PID' and 'NAME.checkpoint.nc.part' beside the run "
                                "directory, so its name may have at most {} bytes",
                                shown.string(), length, NAME_MAX - extra),
                    "--out");
}

/// libnetcdf reads a backslash as a separator (a Windows path): nc_create of
/// 'a\b/.../fields.nc.part' failed with "No such file or directory", exit 1.
void refuse_backslash(const fs::path& path, const fs::path& shown) {
  if (path.string().find('\\') == std::string::npos) return;
  throw ConfigError(fmt::format("--out '{}': the path '{}' holds a backslash, which the NetCDF "
                                "library reads as a directory separator: choose a path without "
                                "one",
                                shown.string(), path.string()),
                    "--out");
}

/// Creates the missing parents of `absolute` (--out `shown`): ConfigError when
/// one of them is a file, std::runtime_error naming the reason otherwise.
void create_parent_directories(const fs::path& absolute, const fs::path& shown) {
  std::error_code ec;
  fs::create_directories(absolute.parent_path(), ec);
  if (!ec) return;
  if (ec == std::errc::too_many_symbolic_link_levels) throw link_loop_error(shown);
  if (ec == std::errc::not_a_directory || ec == std::errc::file_exists) {
    fs::path file = absolute.parent_path();  // the first parent that exists
    std::error_code exists;
    while (file.has_relative_path() && !fs::exists(fs::status(file, exists)))
      file = file.parent_path();
    throw ConfigError(
        fmt::format("--out '{}': '{}' is not a directory", shown.string(), file.string()), "--out");
  }
  throw std::runtime_error(fmt::format("cannot create '{}', the parent directory of --out '{}': {}",
                                       absolute.parent_path().string(), shown.string(),
                                       ec.message()));
}

/// Puts `staging` in the place of the existing directory `target`; afterwards
/// the earlier run is at the returned path.
fs::path swap_into_place(const fs::path& staging, const fs::path& target) {
  if (renameat2(AT_FDCWD, staging.c_str(), AT_FDCWD, target.c_str(), RENAME_EXCHANGE) == 0)
    return staging;
  if (errno != EINVAL && errno != ENOSYS) {
    throw std::runtime_error(fmt::format("cannot exchange '{}' with '{}': {}", staging.string(),
                                         target.string(), system_message(errno)));
  }
  // A file system without RENAME_EXCHANGE: two renames, DIR briefly missing.
  const fs::path old = sibling(target, ".", fmt::format("{}{}", kOldInfix, getpid()));
  fs::rename(target, old);
  std::error_code ec;
  fs::rename(staging, target, ec);
  if (ec) {
    fs::rename(old, target);
    throw std::runtime_error(fmt::format("cannot rename '{}' to '{}': {}", staging.string(),
                                         target.string(), ec.message()));
  }
  return old;
}

/// Puts `staging` in the place of `target`: one atomic exchange when `target`
/// exists, else a rename.  Returns where the earlier `target` is now (empty
/// when there was none), for settle_replacement.
fs::path put_in_place(const fs::path& staging, const fs::path& target, bool target_exists) {
  if (target_exists) return swap_into_place(staging, target);
  fs::rename(staging, target);
  return {};
}

/// After put_in_place: the renames made durable and the earlier contents removed.
void settle_replacement(const fs::path& target, const fs::path& old) {
  sync_path(target.parent_path());
  // Leftovers are the next writer's debris, not this one's failure (noexcept).
  if (!old.empty()) remove_within_mount(old);
}

/// A directory whose mode denies its owner's writes is one the user has
/// protected: a run replaced a 555 directory with a 755 one (access() lets
/// root write anywhere, so it protects only from other users' runs).
void check_writable(const fs::path& dir) {
  if (::access(dir.c_str(), W_OK) == 0) return;
  throw ConfigError(
      fmt::format("--out '{}' is a directory this user may not write ({}): ehlsim "
                  "replaces only a directory it may write; choose another --out, or "
                  "change the directory's mode",
                  dir.string(), std::strerror(errno)));
}

/// A run replaces its directory as a whole (a new inode): a process working
/// in it, or below it, is left in a deleted directory (`cd w; ehlsim spike
/// run --out .` left the shell where `ls` showed nothing and no file could be
/// made).  This process's working directory is the shell's that started it.
void check_not_holding_working_directory(const fs::path& resolved, const fs::path& shown) {
  std::error_code ec;
  const fs::path cwd = fs::current_path(ec);
  if (ec || !holds_path(resolved, cwd)) return;
  throw ConfigError(fmt::format("--out '{}' is the working directory or holds it: ehlsim replaces "
                                "the directory as a whole, which would leave this shell in a "
                                "deleted one; run ehlsim from outside it",
                                shown.string()),
                    "--out");
}

}  // namespace

std::string staging_prefix(std::string_view name) {
  return fmt::format(".{}{}", name, kStagingInfix);
}

std::optional<fs::path> run_directory_staged_in(const fs::path& dir) {
  std::error_code ec;
  const fs::path plain = without_trailing_separator(dir);
  const fs::path resolved = fs::weakly_canonical(plain, ec);  // a link to one, or "."
  const std::string name = (ec ? plain : resolved).filename().string();
  // The name RunDirectory gives its staging_: ".NAME" kStagingInfix "PID".
  const std::size_t infix = name.rfind(kStagingInfix);
  if (!name.starts_with('.') || infix == std::string::npos || infix < 2 ||
      !is_process_id_text(std::string_view(name).substr(infix + kStagingInfix.size())))
    return std::nullopt;
  return (ec ? plain : resolved).parent_path() / name.substr(1, infix - 1);
}

bool holds_path(const fs::path& dir, const fs::path& inside) {
  std::error_code ec;
  const fs::path outer = fs::canonical(dir, ec);
  if (ec) return false;
  const fs::path inner = fs::canonical(inside, ec);
  if (ec) return false;
  return std::mismatch(outer.begin(), outer.end(), inner.begin(), inner.end()).first == outer.end();
}

const fs::path& refuse_non_directory(const fs::path& shown) {
  std::error_code ec;
  const fs::file_status status = fs::status(shown, ec);
  if (fs::exists(status) && !fs::is_directory(status)) {
    throw ConfigError(fmt::format("--out '{}' exists and is not a directory", shown.string()),
                      "--out");
  }
  return shown;
}

void check_no_mount_point(const fs::path& dir) {
  std::error_code ec;
  const fs::path resolved = fs::weakly_canonical(dir, ec);  // DIR a link to a mount point
  refuse_mount_points(ec ? dir : resolved, dir);
}

void check_replaceable_run_directory(const fs::path& dir) {
  std::error_code ec;
  if (!fs::exists(fs::status(refuse_non_directory(dir), ec))) return;
  check_writable(dir);
  check_no_mount_point(dir);
  if (fs::is_empty(dir, ec)) return;
  const char* policy =
      "ehlsim writes only into a new or empty directory or over an earlier ehlsim run; "
      "choose another --out, or move the files yourself";
  if (!is_ehlsim_run_json(dir / "run.json")) {
    throw ConfigError(fmt::format("--out '{}' is not empty and holds no ehlsim run.json: {}",
                                  dir.string(), policy));
  }
  if (const fs::path foreign = first_foreign_entry(dir); !foreign.empty()) {
    throw ConfigError(fmt::format("--out '{}' holds '{}', which ehlsim did not write: {}",
                                  dir.string(), foreign.string(), policy));
  }
  if (const fs::path busy = first_held_lock(dir); !busy.empty()) {
    throw ConfigError(
        fmt::format("--out '{}' holds '{}', the lock of an ehlsim run that writes "
                    "there now: wait for it to end, or choose another --out",
                    dir.string(), busy.string()));
  }
}

void replace_directory(const fs::path& staging, const fs::path& target) {
  try {
    check_no_mount_point(target);  // one mounted since the caller's check
  } catch (const ConfigError& e) {
    throw std::runtime_error(e.what());
  }
  sync_path(staging);
  settle_replacement(target, put_in_place(staging, target, fs::exists(fs::symlink_status(target))));
}

PathLock::PathLock(const fs::path& target, const fs::path& shown)
    : path_(sibling(target, ".", kLockSuffix)) {
  // A file of the user's by the lock's name was truncated, then deleted.
  std::error_code ec;
  const fs::file_status status = fs::symlink_status(path_, ec);
  if (fs::exists(status) && !(fs::is_regular_file(status) && is_ehlsim_lock(path_))) {
    throw ConfigError(fmt::format("--out '{}': '{}' beside it is not an ehlsim lock (ehlsim locks "
                                  "the run directory with a file of that name): move it, or "
                                  "choose another --out",
                                  shown.string(), path_.string()),
                      "--out");
  }
  for (;;) {
    fd_ = open(path_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd_ < 0) {
      throw std::runtime_error(
          fmt::format("cannot create lock file '{}': {}", path_.string(), system_message(errno)));
    }
    if (flock(fd_, LOCK_EX | LOCK_NB) != 0) {
      const std::string holder = read_lock_holder(fd_);
      close(fd_);
      fd_ = -1;
      throw ConfigError(fmt::format(
          "--out '{}' is in use by another ehlsim run ({}; lock file '{}'): wait for it to end or "
          "choose another --out",
          shown.string(), holder, path_.string()));
    }
    // The holder before us may have removed the file after we opened it: the
    // lock counts only on the file that is still there.
    struct stat held {};
    struct stat current {};
    if (fstat(fd_, &held) == 0 && stat(path_.c_str(), &current) == 0 &&
        held.st_ino == current.st_ino && held.st_dev == current.st_dev)
      break;
    close(fd_);
  }
  const std::string text = lock_holder_text();
  // Should this fail, only the message of a second run lacks the holder.
  if (ftruncate(fd_, 0) == 0) (void)!pwrite(fd_, text.data(), text.size(), 0);
}

PathLock::~PathLock() { release(); }

void PathLock::release() noexcept {
  if (fd_ < 0) return;
  unlink(path_.c_str());  // while still locked: see the stat check above
  close(fd_);
  fd_ = -1;
}

ConfigError link_loop_error(const fs::path& shown) {
  return ConfigError(
      fmt::format("--out '{}': too many levels of symbolic links (a loop?)", shown.string()),
      "--out");
}

fs::path resolve_run_directory(const fs::path& target) {
  if (target.empty()) throw ConfigError("--out '': the run directory needs a name", "--out");
  std::error_code ec;
  const fs::path from_cwd = fs::absolute(target, ec);
  if (ec) {
    // getcwd(3) fails in a working directory that was deleted.
    throw ConfigError(fmt::format("--out '{}': the working directory is unknown ({}; was it "
                                  "deleted?): give --out as an absolute path, or run from an "
                                  "existing directory",
                                  target.string(), ec.message()),
                      "--out");
  }
  // Resolved as the kernel does: "link/../run" is beside the link's target, not
  // "run" (the checks looked at one directory and the swap replaced another).
  fs::path absolute = without_trailing_separator(from_cwd);
  if (absolute.filename() == "." || absolute.filename() == "..")
    absolute = without_trailing_separator(fs::weakly_canonical(absolute));
  if (absolute.filename().empty() || absolute.filename() == "..") {
    throw ConfigError(
        fmt::format("--out '{}': not a directory ehlsim can replace", target.string()), "--out");
  }
  refuse_backslash(absolute, target);
  // The parent's missing tail is taken lexically: "nosuch/../run" makes no "nosuch".
  fs::path parent = fs::weakly_canonical(absolute.parent_path(), ec);
  if (ec == std::errc::too_many_symbolic_link_levels) throw link_loop_error(target);
  if (ec) parent = absolute.parent_path().lexically_normal();
  const fs::path resolved = parent / absolute.filename();
  refuse_backslash(resolved, target);  // one behind a link ("lnk/run", lnk -> 'x\y')
  check_name_leaves_room(resolved, target);
  create_parent_directories(resolved, target);
  return resolved;
}

RunDirectory::RunDirectory(const fs::path& target)
    : target_(refuse_non_directory(without_trailing_separator(target))),
      directory_(follow_final_link(target_)),
      resolved_(resolve_run_directory(directory_)),
      lock_(resolved_, target_),
      staging_(sibling(resolved_, ".", fmt::format("{}{}", kStagingInfix, getpid()))) {
  check_replaceable_run_directory(target_);  // with its mount points
  check_not_holding_working_directory(resolved_, target_);
  remove_debris(resolved_);
  entries_at_start_ = entries_below(resolved_, {}, target_);
  checkpoint_at_start_ = stamp_of(checkpoint());
  fs::create_directory(staging_);
}

RunDirectory::RunDirectory(const fs::path& target, const Amend& amend)
    : target_(refuse_non_directory(without_trailing_separator(target))),
      directory_(follow_final_link(target_)),
      resolved_(resolve_run_directory(directory_)),
      lock_(resolved_, target_),
      staging_(sibling(resolved_, ".", fmt::format("{}{}", kStagingInfix, getpid()))),
      amend_(true),
      replaced_(amend.replaced) {
  // Again under the lock: the check before it raced with other processes.
  std::error_code ec;
  if (fs::exists(fs::status(refuse_non_directory(target_), ec))) check_writable(target_);
  check_not_holding_working_directory(resolved_, target_);
  refuse_mount_points(resolved_, target_);
  refuse_uncarriable_entries(resolved_, replaced_, target_);
  remove_debris(resolved_);
  fs::create_directory(staging_);
}

RunDirectory::~RunDirectory() {
  if (published_) return;
  remove_within_mount(staging_);  // noexcept: nothing to report from a destructor
  // Out of descriptors (ulimit -n), the lock's may be the last this process
  // may have: the removal could not open the staging directory, and it stayed.
  if (std::error_code ec; fs::exists(fs::symlink_status(staging_, ec))) {
    lock_.release();
    remove_within_mount(staging_);
  }
}

fs::path RunDirectory::checkpoint() const {
  // Beside the directory the run replaces.  As given where no "." or ".."
  // can lead elsewhere ("nosuch/../g4" failed, "link/../g5" wrote beside the
  // link's target, "run/." into run), so that messages keep the user's path.
  const bool plain = std::none_of(directory_.begin(), directory_.end(),
                                  [](const fs::path& part) { return part == "." || part == ".."; });
  return sibling(plain ? directory_ : resolved_, "", kCheckpointSuffix);
}

void RunDirectory::refuse_foreign_checkpoint() const {
  const fs::path checkpoint = this->checkpoint();
  const fs::path partial = checkpoint.string() + PartialFile::kSuffix;
  for (const fs::path& path : {checkpoint, partial}) {
    std::error_code ec;
    const fs::file_status status = fs::symlink_status(path, ec);
    std::string why;
    std::string way_out = "move it";
    if (fs::is_symlink(status)) {
      why = fmt::format("'{}' is a symbolic link", path.string());
    } else if (fs::exists(status) && is_mount_point(path, device_of_parent(path))) {
      // Renamed over at the first checkpoint: EBUSY after the work.
      why = fmt::format("'{}' is a mount point", path.string());
      way_out = "unmount it";
    } else if (fs::exists(status) &&
               !(path == partial && fs::is_regular_file(status) && fs::is_empty(path, ec))) {
      try {
        require_netcdf4_file(path, "replace");
      } catch (const SystemFailure&) {
        throw;  // an I/O error says nothing of whose file it is
      } catch (const std::runtime_error& e) {
        why = e.what();
      }
    }
    if (!why.empty())
      throw ConfigError(fmt::format("--out '{}': a run keeps its checkpoint beside it, and {}: "
                                    "{}, or choose another --out",
                                    target_.string(), why, way_out),
                        "--out");
  }
}

fs::path RunDirectory::staged_checkpoint() const { return staging_ / kCheckpointFile; }

void RunDirectory::stage_checkpoint() {
  // A copy, not a link: a file written over checkpoint() would change it too.
  copy_contents(checkpoint(), staged_checkpoint());
  checkpoint_written_ = stamp_of(checkpoint());
}

void RunDirectory::publish(bool resumed_from_checkpoint) {
  if (amend_) {
    // Now, not at the start: DIR may change in a long analysis (ehlsim spike locks
    // it only against other ehlsim processes).
    carried_ = entries_below(resolved_, replaced_, target_);
    carry_over(resolved_, staging_, carried_);
    if (fs::exists(resolved_)) copy_directory_attributes(resolved_, staging_);
  } else if (fs::exists(resolved_)) {
    // A rerun made DIR anew: a private (700) directory came back 755.
    copy_directory_mode(resolved_, staging_);
  }
  sync_path(staging_);
  stop_here_for_tests("publish");
  refuse_mount_in_staging();
  check_target_unchanged();
  if (const int signal = InterruptGuard::received(); signal != 0) throw PublishInterrupted(signal);
  const fs::path old = put_in_place(staging_, resolved_, fs::exists(resolved_));
  published_ = true;
  settle_replacement(resolved_, old);
  // The checkpoint went along as DIR/checkpoint.nc, or the run completed
  // the one it resumed.  Any other stays: an interrupted run's, which a run
  // without checkpoints or a rolling run into DIR deleted.
  const FileStamp beside = stamp_of(checkpoint());
  const bool own = beside.device != 0 && beside == checkpoint_written_;
  const bool resumed =
      resumed_from_checkpoint && beside.device != 0 && beside == checkpoint_at_start_;
  std::error_code ec;
  if (own || resumed) fs::remove(checkpoint(), ec);
}

void RunDirectory::refuse_mount_in_staging() const {
  // Mounted over, the rename failed with a bare "filesystem error: ... busy".
  if (is_mount_point(staging_, device_of_parent(staging_))) {
    throw std::runtime_error(fmt::format(
        "'{}', where ehlsim writes the run before it replaces '{}', was mounted over during the "
        "run: nothing was published; unmount it (the next run into '{}' removes it)",
        staging_.string(), target_.string(), target_.string()));
  }
  // Published, it would become part of DIR, which the next run cannot replace.
  if (const fs::path mount = first_mount_point_below(staging_); !mount.empty()) {
    throw std::runtime_error(fmt::format(
        "'{}' was mounted during the run in '{}', where ehlsim writes the run before it "
        "replaces '{}': nothing was published; unmount it",
        mount.string(), staging_.string(), target_.string()));
  }
}

void RunDirectory::check_target_unchanged() const {
  if (!amend_) {
    try {
      check_replaceable_run_directory(target_);  // a file put there during the run stays
    } catch (const ConfigError& e) {
      throw std::runtime_error(e.what());
    }
    // So does a run or an analysis that wrote into a subdirectory of DIR and
    // ended meanwhile (`ehlsim spike DIR --out DIR/gauss`): its files are
    // ehlsim's and its lock is gone, but it is not the run this one replaces.
    for (const CarriedEntry& entry : entries_below(resolved_, {}, target_)) {
      if (std::find(entries_at_start_.begin(), entries_at_start_.end(), entry) ==
          entries_at_start_.end()) {
        throw std::runtime_error(fmt::format(
            "'{}' gained '{}' during the run (another program or ehlsim run wrote it): it was "
            "left as it was",
            target_.string(), (target_ / entry.relative).string()));
      }
    }
  } else if (entries_below(resolved_, replaced_, target_) != carried_) {
    // The swap would drop what came meanwhile, or bring back what went.
    throw std::runtime_error(
        fmt::format("'{}' changed while its files were carried over (an entry added, removed or "
                    "replaced by another program): it was left as it was",
                    target_.string()));
  }
}

}  // namespace ehlsim

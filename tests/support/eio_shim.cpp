// TEST ONLY: an LD_PRELOAD library that makes writes to chosen files fail with
// EIO, the I/O error no disk of a test machine can be made to give.  It is
// built for the tests alone (tests/CMakeLists.txt) and never linked into
// ehlsim.
//
// Environment of the process it is preloaded into:
//   EHLSIM_TEST_EIO_PATH   a substring of the path of the files to fail (the
//                          target of /proc/self/fd/N); unset or empty: the
//                          library only passes every call on.
//   EHLSIM_TEST_EIO_AFTER  bytes the matching files may take in all before
//                          the writes fail (default 0: the first one fails), so
//                          that a file can fail in the middle.  A call that
//                          would go beyond fails whole, writing nothing.  The
//                          count is shared with the child processes ehlsim
//                          writes its NetCDF files in (io/IsolatedIo.hpp).
//   EHLSIM_TEST_EIO_OFFSET a file offset: only the writes that start there
//                          count, one each, and EHLSIM_TEST_EIO_AFTER is the
//                          number of them that succeed.  Offset 0 is HDF5's
//                          superblock, which it writes when it creates a file,
//                          ends its definitions, and twice when it closes it:
//                          the last write of every file, whatever its size.
//   EHLSIM_TEST_EIO_FSYNC  "1": fsync and fdatasync of the matching files fail
//                          instead (the writes succeed), as when the kernel's
//                          writeback of the page cache found the disk failing.
//   EHLSIM_TEST_EIO_READ_AT a file offset: the reads of the matching files that
//                          reach it fail instead (the writes succeed), as
//                          from a bad sector there.  Unset or empty: reads
//                          are passed on.
//
// The calls that read are read and pread (pread64, readv, preadv likewise): HDF5's
// sec2 driver reads with pread; stdio's fread, as fwrite, cannot be replaced.
// The calls that write into files in ehlsim's process: write and writev
// (libstdc++'s std::ofstream: the CSV files, run.json), pwrite (HDF5's sec2
// driver under NetCDF-4: fields.nc, checkpoint.nc), pwrite64 and pwritev (the
// same under _FILE_OFFSET_BITS=64 or in other builds).  stdio's fwrite reaches
// the kernel through glibc's internal write, which no preload can replace;
// ehlsim writes no file with it.  Each call is passed on to the next
// definition (dlsym(RTLD_NEXT)): libc's, or the sanitizer runtime's.
#include <dlfcn.h>
#include <sys/mman.h>
#include <sys/types.h>
#include <sys/uio.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <new>

namespace {

/// Bytes the matching files have taken, in a page shared with the children
/// forked later (mapped when the library is loaded, before any fork).
std::atomic<long long>& shared_count() {
  void* page = mmap(nullptr, sizeof(std::atomic<long long>), PROT_READ | PROT_WRITE,
                    MAP_SHARED | MAP_ANONYMOUS, -1, 0);
  if (page == MAP_FAILED) std::abort();
  return *new (page) std::atomic<long long>{0};
}

std::atomic<long long>& written = shared_count();

template <class Function>
Function* next(const char* name) {
  return reinterpret_cast<Function*>(dlsym(RTLD_NEXT, name));
}

/// Whether `fd` is open on a file whose path contains EHLSIM_TEST_EIO_PATH.
bool matches(int fd) {
  const char* substring = std::getenv("EHLSIM_TEST_EIO_PATH");
  if (substring == nullptr || *substring == '\0' || fd < 0) return false;
  char link[32];
  std::snprintf(link, sizeof(link), "/proc/self/fd/%d", fd);
  char path[4096];
  const ssize_t length = readlink(link, path, sizeof(path) - 1);
  if (length <= 0) return false;
  path[length] = '\0';
  return std::strstr(path, substring) != nullptr;
}

bool fsync_fails() {
  const char* flag = std::getenv("EHLSIM_TEST_EIO_FSYNC");
  return flag != nullptr && std::strcmp(flag, "1") == 0;
}

/// The offset EHLSIM_TEST_EIO_READ_AT, or -1 when the reads pass.
long long read_failure_offset() {
  const char* at = std::getenv("EHLSIM_TEST_EIO_READ_AT");
  return at == nullptr || *at == '\0' ? -1 : std::atoll(at);
}

/// A write(2) or writev(2): it starts where the file's position is.
constexpr off64_t kAtPosition = -1;

/// `offset`, or the position of `fd` for kAtPosition (errno kept).
off64_t resolved(int fd, off64_t offset) {
  if (offset != kAtPosition) return offset;
  const int saved = errno;
  offset = lseek64(fd, 0, SEEK_CUR);
  errno = saved;
  return offset;
}

/// What a write of `bytes` at `offset` takes of the budget: its bytes, or with
/// EHLSIM_TEST_EIO_OFFSET one write if it starts there and nothing otherwise.
long long cost(int fd, std::size_t bytes, off64_t offset) {
  const char* at = std::getenv("EHLSIM_TEST_EIO_OFFSET");
  if (at == nullptr || *at == '\0') return static_cast<long long>(bytes);
  return resolved(fd, offset) == std::atoll(at) ? 1 : 0;
}

/// Whether a write of `bytes` into `fd` at `offset` fails (EIO set); counts it
/// if not.
bool fails(int fd, std::size_t bytes, off64_t offset) {
  if (fsync_fails() || read_failure_offset() >= 0 || !matches(fd)) return false;
  const char* after = std::getenv("EHLSIM_TEST_EIO_AFTER");
  const long long budget = after == nullptr ? 0 : std::atoll(after);
  const long long taken = cost(fd, bytes, offset);
  if (taken > 0 && written.load() + taken > budget) {
    errno = EIO;
    return true;
  }
  written += taken;
  return false;
}

/// Whether a read of `bytes` from `fd` at `offset` (kAtPosition: where the
/// file's position is) fails (EIO set): it reaches EHLSIM_TEST_EIO_READ_AT.
bool read_fails(int fd, std::size_t bytes, off64_t offset) {
  const long long at = read_failure_offset();
  if (at < 0 || bytes == 0 || !matches(fd)) return false;
  if (resolved(fd, offset) + static_cast<off64_t>(bytes) <= at) return false;
  errno = EIO;
  return true;
}

std::size_t total(const iovec* iov, int count) {
  std::size_t bytes = 0;
  for (int i = 0; i < count; ++i) bytes += iov[i].iov_len;
  return bytes;
}

/// A sync of `fd` by `real` (fsync or fdatasync), or EIO where it is to fail.
int synced(int fd, int (*real)(int)) {
  if (fsync_fails() && matches(fd)) {
    errno = EIO;
    return -1;
  }
  return real(fd);
}

}  // namespace

extern "C" {

ssize_t write(int fd, const void* buffer, std::size_t count) {
  static auto* real = next<ssize_t(int, const void*, std::size_t)>("write");
  return fails(fd, count, kAtPosition) ? -1 : real(fd, buffer, count);
}

ssize_t pwrite(int fd, const void* buffer, std::size_t count, off_t offset) {
  static auto* real = next<ssize_t(int, const void*, std::size_t, off_t)>("pwrite");
  return fails(fd, count, offset) ? -1 : real(fd, buffer, count, offset);
}

ssize_t pwrite64(int fd, const void* buffer, std::size_t count, off64_t offset) {
  static auto* real = next<ssize_t(int, const void*, std::size_t, off64_t)>("pwrite64");
  return fails(fd, count, offset) ? -1 : real(fd, buffer, count, offset);
}

ssize_t writev(int fd, const iovec* iov, int count) {
  static auto* real = next<ssize_t(int, const iovec*, int)>("writev");
  return fails(fd, total(iov, count), kAtPosition) ? -1 : real(fd, iov, count);
}

ssize_t pwritev(int fd, const iovec* iov, int count, off_t offset) {
  static auto* real = next<ssize_t(int, const iovec*, int, off_t)>("pwritev");
  return fails(fd, total(iov, count), offset) ? -1 : real(fd, iov, count, offset);
}

ssize_t read(int fd, void* buffer, std::size_t count) {
  static auto* real = next<ssize_t(int, void*, std::size_t)>("read");
  return read_fails(fd, count, kAtPosition) ? -1 : real(fd, buffer, count);
}

ssize_t pread(int fd, void* buffer, std::size_t count, off_t offset) {
  static auto* real = next<ssize_t(int, void*, std::size_t, off_t)>("pread");
  return read_fails(fd, count, offset) ? -1 : real(fd, buffer, count, offset);
}

ssize_t pread64(int fd, void* buffer, std::size_t count, off64_t offset) {
  static auto* real = next<ssize_t(int, void*, std::size_t, off64_t)>("pread64");
  return read_fails(fd, count, offset) ? -1 : real(fd, buffer, count, offset);
}

ssize_t readv(int fd, const iovec* iov, int count) {
  static auto* real = next<ssize_t(int, const iovec*, int)>("readv");
  return read_fails(fd, total(iov, count), kAtPosition) ? -1 : real(fd, iov, count);
}

ssize_t preadv(int fd, const iovec* iov, int count, off_t offset) {
  static auto* real = next<ssize_t(int, const iovec*, int, off_t)>("preadv");
  return read_fails(fd, total(iov, count), offset) ? -1 : real(fd, iov, count, offset);
}

int fsync(int fd) {
  static auto* real = next<int(int)>("fsync");
  return synced(fd, real);
}

int fdatasync(int fd) {
  static auto* real = next<int(int)>("fdatasync");
  return synced(fd, real);
}

}  // extern "C"

#include "cairn/util/atomic_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <string>

namespace cairn::util {
namespace {

std::string SystemError(int error) { return std::strerror(error); }

/// A name no other writer (thread or process) uses at the same time.
std::filesystem::path TempPathFor(const std::filesystem::path& path) {
  static std::atomic<unsigned> counter{0};
  std::filesystem::path temp = path;
  temp.replace_filename("." + path.filename().string() + ".tmp." + std::to_string(::getpid()) +
                        "." + std::to_string(counter.fetch_add(1)));
  return temp;
}

}  // namespace

Status WriteFileAtomic(const std::filesystem::path& path, std::string_view bytes) {
  const std::string name = path.string();
  if (path.filename().empty()) return Error{name + ": not a file name"};
  const std::filesystem::path temp = TempPathFor(path);

  const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) {
    return Error{name + ": cannot create a temporary file in its directory: " + SystemError(errno)};
  }
  const auto fail = [&](const std::string& what, int error) -> Status {
    ::close(fd);
    ::unlink(temp.c_str());
    return Error{name + ": " + what + ": " + SystemError(error)};
  };
  const char* data = bytes.data();
  std::size_t left = bytes.size();
  while (left > 0) {
    const ssize_t n = ::write(fd, data, left);
    if (n < 0) {
      if (errno == EINTR) continue;
      return fail("write failed", errno);
    }
    data += n;
    left -= static_cast<std::size_t>(n);
  }
  // Flush before the rename so that a crash cannot leave the new name on empty data.
  if (::fsync(fd) != 0) return fail("fsync failed", errno);
  if (::close(fd) != 0) {
    const int error = errno;
    ::unlink(temp.c_str());
    return Error{name + ": close failed: " + SystemError(error)};
  }
  if (std::rename(temp.c_str(), path.c_str()) != 0) {
    const int error = errno;
    ::unlink(temp.c_str());
    return Error{name + ": cannot rename the temporary file into place: " + SystemError(error)};
  }
  // Make the rename itself durable; best effort, the file is complete either way.
  std::filesystem::path dir = path.parent_path();
  if (dir.empty()) dir = ".";
  if (const int dir_fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC); dir_fd >= 0) {
    ::fsync(dir_fd);
    ::close(dir_fd);
  }
  return Status::Ok();
}

Status WriteFileAt(const std::filesystem::path& path, std::uint64_t at, std::string_view bytes) {
  const std::string name = path.string();
  // Created only when nothing of it is to be kept.
  const int fd = ::open(path.c_str(), O_WRONLY | O_CLOEXEC | (at == 0 ? O_CREAT : 0), 0644);
  if (fd < 0) return Error{name + ": cannot open for writing: " + SystemError(errno)};
  const auto fail = [&](const std::string& what, int error) -> Status {
    ::close(fd);
    return Error{name + ": " + what + ": " + SystemError(error)};
  };
  struct stat st {};
  if (::fstat(fd, &st) != 0) return fail("cannot read its size", errno);
  if (static_cast<std::uint64_t>(st.st_size) < at) {
    ::close(fd);
    return Error{name + ": holds " + std::to_string(st.st_size) + " bytes, expected at least " +
                 std::to_string(at)};
  }
  if (::ftruncate(fd, static_cast<off_t>(at)) != 0) return fail("cannot cut it", errno);
  const char* data = bytes.data();
  std::size_t left = bytes.size();
  auto offset = static_cast<off_t>(at);
  while (left > 0) {
    const ssize_t n = ::pwrite(fd, data, left, offset);
    if (n < 0) {
      if (errno == EINTR) continue;
      return fail("write failed", errno);
    }
    data += n;
    offset += n;
    left -= static_cast<std::size_t>(n);
  }
  if (::fsync(fd) != 0) return fail("fsync failed", errno);
  if (::close(fd) != 0) return Error{name + ": close failed: " + SystemError(errno)};
  return Status::Ok();
}

}  // namespace cairn::util

#include "FileParameterStorage.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <utility>

namespace linuxhw {
namespace {

// Closes a file descriptor on every return path.
class Fd {
 public:
  explicit Fd(int fd) : fd_(fd) {}
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  ~Fd() {
    if (fd_ >= 0) ::close(fd_);
  }
  int get() const { return fd_; }
  // close() reports write-back errors on some file systems: check it.
  bool close() {
    const int fd = std::exchange(fd_, -1);
    return ::close(fd) == 0;
  }

 private:
  int fd_;
};

std::string directory_of(const std::string& path) {
  const auto slash = path.rfind('/');
  if (slash == std::string::npos) return ".";
  if (slash == 0) return "/";
  return path.substr(0, slash);
}

}  // namespace

FileParameterStorage::FileParameterStorage(std::string path)
    : path_(std::move(path)), temp_path_(path_ + ".tmp"), directory_(directory_of(path_)) {}

bool FileParameterStorage::fail(const std::string& what) {
  last_error_ = what + ": " + std::strerror(errno);
  return false;
}

bool FileParameterStorage::save(std::span<const std::byte> image) {
  Fd file(::open(temp_path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644));
  if (file.get() < 0) return fail("cannot create " + temp_path_);
  std::size_t written = 0;
  while (written < image.size()) {
    const ssize_t n = ::write(file.get(), image.data() + written, image.size() - written);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      fail("cannot write " + temp_path_);
      ::unlink(temp_path_.c_str());
      return false;
    }
    written += static_cast<std::size_t>(n);
  }
  // Data on disk before the rename makes it visible; otherwise a crash could expose an empty
  // file under the final name.
  if (::fsync(file.get()) != 0 || !file.close()) {
    fail("cannot flush " + temp_path_);
    ::unlink(temp_path_.c_str());
    return false;
  }
  if (::rename(temp_path_.c_str(), path_.c_str()) != 0) {
    fail("cannot rename " + temp_path_ + " to " + path_);
    ::unlink(temp_path_.c_str());
    return false;
  }
  // The rename itself is durable only once the directory entry is.
  Fd directory(::open(directory_.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC));
  if (directory.get() < 0) return fail("cannot open directory " + directory_);
  if (::fsync(directory.get()) != 0) return fail("cannot flush directory " + directory_);
  last_error_.clear();
  return true;
}

std::size_t FileParameterStorage::load(std::span<std::byte> buffer) {
  // A temporary file here is what a save() killed before its rename left behind: never a
  // completed store, so never the image to load, and the next save() truncates it anyway.
  // Removed at load (start-up) so a crash leaves nothing beside the parameter file. ENOENT is
  // the normal case; any other failure only leaves the stray file, no reason to refuse the load.
  (void)::unlink(temp_path_.c_str());
  Fd file(::open(path_.c_str(), O_RDONLY | O_CLOEXEC));
  if (file.get() < 0) {
    if (errno == ENOENT) {
      last_error_.clear();  // nothing stored yet is not an error
      return 0;
    }
    fail("cannot open " + path_);
    return 0;
  }
  std::size_t total = 0;
  while (true) {
    if (total == buffer.size()) {
      // Full buffer: anything more means the file is larger than any valid image.
      std::byte extra{};
      ssize_t n = 0;
      do n = ::read(file.get(), &extra, 1); while (n < 0 && errno == EINTR);
      if (n != 0) {
        last_error_ = path_ + " is larger than " + std::to_string(buffer.size()) + " bytes";
        return 0;
      }
      break;
    }
    const ssize_t n = ::read(file.get(), buffer.data() + total, buffer.size() - total);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      fail("cannot read " + path_);
      return 0;
    }
    if (n == 0) break;
    total += static_cast<std::size_t>(n);
  }
  last_error_.clear();
  return total;
}

}  // namespace linuxhw

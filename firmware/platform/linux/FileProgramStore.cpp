#include "FileProgramStore.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <utility>

#include "canopen/ParameterImage.hpp"

namespace linuxhw {
namespace {

bool fsync_directory(const std::string& directory) {
  const int fd = ::open(directory.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return false;
  const bool ok = ::fsync(fd) == 0;
  ::close(fd);
  return ok;
}

}  // namespace

FileProgramStore::FileProgramStore(std::string directory)
    : directory_(std::move(directory)),
      part_path_(directory_ + "/staged.part"),
      staged_path_(directory_ + "/staged.img"),
      running_path_(directory_ + "/running.img") {
  // What a previous process left staged is not known to this one's node: never started.
  ::unlink(part_path_.c_str());
  ::unlink(staged_path_.c_str());
  buffer_.reserve(kBufferBytes);
}

FileProgramStore::~FileProgramStore() { close_staging(); }

bool FileProgramStore::fail(const std::string& what) {
  last_error_ = what + ": " + std::strerror(errno);
  return false;
}

void FileProgramStore::close_staging() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  buffer_.clear();
}

bool FileProgramStore::open_staging() {
  discard_staging();
  fd_ = ::open(part_path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0755);
  if (fd_ < 0) return fail("cannot create " + part_path_);
  return true;
}

bool FileProgramStore::write_staging(std::span<const std::uint8_t> bytes) {
  if (fd_ < 0) return false;
  buffer_.insert(buffer_.end(), bytes.begin(), bytes.end());
  return buffer_.size() < kBufferBytes || flush();
}

bool FileProgramStore::flush() {
  std::size_t written = 0;
  while (written < buffer_.size()) {
    const ssize_t n = ::write(fd_, buffer_.data() + written, buffer_.size() - written);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return fail("cannot write " + part_path_);
    written += static_cast<std::size_t>(n);
  }
  buffer_.clear();
  return true;
}

bool FileProgramStore::commit_staging() {
  if (fd_ < 0) return false;
  if (!flush()) return false;
  const bool synced = ::fsync(fd_) == 0;
  const bool closed = ::close(fd_) == 0;
  fd_ = -1;
  if (!synced || !closed) return fail("cannot write " + part_path_);
  if (::chmod(part_path_.c_str(), 0755) != 0) return fail("cannot chmod " + part_path_);
  if (::rename(part_path_.c_str(), staged_path_.c_str()) != 0) return fail("cannot rename " + part_path_);
  (void)fsync_directory(directory_);
  return true;
}

void FileProgramStore::discard_staging() {
  close_staging();
  ::unlink(part_path_.c_str());
  ::unlink(staged_path_.c_str());
}

std::uint32_t FileProgramStore::running_image_crc32() {
  if (crc_known_) return crc_;
  const int fd = ::open("/proc/self/exe", O_RDONLY | O_CLOEXEC);
  if (fd < 0) return 0;
  std::array<std::byte, 64 * 1024> buffer{};
  std::uint32_t crc = 0;
  for (;;) {
    const ssize_t n = ::read(fd, buffer.data(), buffer.size());
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      ::close(fd);
      return 0;
    }
    if (n == 0) break;
    crc = co::parameter_image::crc32(std::span(buffer).first(static_cast<std::size_t>(n)), crc);
  }
  ::close(fd);
  crc_ = crc;
  crc_known_ = true;
  return crc_;
}

std::string FileProgramStore::promote_staged() {
  if (::rename(staged_path_.c_str(), running_path_.c_str()) != 0) {
    fail("cannot rename " + staged_path_);
    return {};
  }
  (void)fsync_directory(directory_);
  return running_path_;
}

}  // namespace linuxhw

// co::ProgramStore on Linux files, for CiA 302-3 program download (ProgramDownload.hpp): the
// images live side by side in one directory (--image-dir) of their own, never over the build's
// executable that other processes may run:
//   DIR/staged.part  the download under way, written as it arrives, 64 KiB at a time (removed
//                    when it breaks off, and at start-up: a process killed mid-download leaves
//                    no half image);
//   DIR/staged.img   a complete, checked image, renamed from staged.part after an fsync;
//   DIR/running.img  the image Start made current: renamed from staged.img (atomic), then the
//                    process execv()s it with its own argv.
// The running executable is never opened for writing: a download that breaks off leaves it as
// it was, and the process keeps running.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "canopen/ProgramDownload.hpp"

namespace linuxhw {

class FileProgramStore final : public co::ProgramStore {
 public:
  // `directory` must exist. Removes what an earlier process left staged (a staged.part a kill
  // cut short, a staged.img never started): this process's node knows of neither.
  explicit FileProgramStore(std::string directory);
  ~FileProgramStore() override;
  FileProgramStore(const FileProgramStore&) = delete;
  FileProgramStore& operator=(const FileProgramStore&) = delete;

  bool open_staging() override;
  bool write_staging(std::span<const std::uint8_t> bytes) override;
  bool commit_staging() override;
  void discard_staging() override;
  // CRC-32 of /proc/self/exe, read once at the first call (the file does not change under a
  // running process: a new image only ever arrives by rename).
  std::uint32_t running_image_crc32() override;

  // Makes the kept image the running one (rename, atomic) and returns its path for execv; empty
  // on failure (see last_error()).
  std::string promote_staged();
  const std::string& last_error() const { return last_error_; }

 private:
  bool fail(const std::string& what);
  void close_staging();
  bool flush();

  std::string directory_;
  std::string part_path_;
  std::string staged_path_;
  std::string running_path_;
  int fd_ = -1;
  // The payload arrives 7 bytes a frame: written a buffer at a time, not a system call a frame.
  static constexpr std::size_t kBufferBytes = 64 * 1024;
  std::vector<std::uint8_t> buffer_;
  bool crc_known_ = false;
  std::uint32_t crc_ = 0;
  std::string last_error_;
};

}  // namespace linuxhw

// co::ParameterStorage on a Linux file, replaced atomically: the image goes to a temporary file
// in the same directory, is fsync'ed, renamed over the old one, and the directory is fsync'ed.
// A kill or power cut at any moment leaves either the old or the new file, never a torn one.
#pragma once

#include <cstddef>
#include <span>
#include <string>

#include "Interfaces.hpp"

namespace linuxhw {

class FileParameterStorage final : public co::ParameterStorage {
 public:
  // `path`: the parameter file; its directory must exist. Nothing is touched until save/load.
  explicit FileParameterStorage(std::string path);
  FileParameterStorage(const FileParameterStorage&) = delete;
  FileParameterStorage& operator=(const FileParameterStorage&) = delete;

  // true: the new image is durable. false: see last_error(); if writing or renaming failed the
  // old file is untouched, if only the final directory fsync failed the new file is in place
  // but its rename may not survive a power cut.
  bool save(std::span<const std::byte> image) override;
  // Size of the file copied into `buffer`; 0 when it does not exist, cannot be read, or does
  // not fit `buffer` (see last_error()). Also removes the temporary file a save() killed before
  // its rename leaves behind (it never holds a completed store).
  std::size_t load(std::span<std::byte> buffer) override;

  const std::string& path() const { return path_; }
  // What the last failing call could not do, with strerror text; empty after success.
  const std::string& last_error() const { return last_error_; }

 private:
  bool fail(const std::string& what);

  std::string path_;
  std::string temp_path_;
  std::string directory_;
  std::string last_error_;
};

}  // namespace linuxhw

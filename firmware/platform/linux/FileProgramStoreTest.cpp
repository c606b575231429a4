// FileProgramStore: staging a download a buffer at a time, commit and discard, what an earlier
// process left, promotion to the running image, and failures reported with their cause.
#include "FileProgramStore.hpp"

#include <gtest/gtest.h>
#include <stdlib.h>
#include <sys/stat.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace linuxhw {
namespace {

namespace fs = std::filesystem;

constexpr std::size_t kSegmentBytes = 7;  // what one SDO segment carries

std::vector<std::uint8_t> image_of(std::size_t size) {
  std::vector<std::uint8_t> image(size);
  for (std::size_t i = 0; i < size; ++i) image[i] = static_cast<std::uint8_t>((i * 31 + i / 251) & 0xFFu);
  return image;
}

std::vector<std::uint8_t> read_file(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_file(const fs::path& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }

class FileProgramStoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::temp_directory_path() / "fw-images-XXXXXX").string();
    ASSERT_NE(::mkdtemp(pattern.data()), nullptr);
    dir = pattern;
  }
  void TearDown() override { fs::remove_all(dir); }

  // Writes `bytes` as the node does, a segment at a time; false at the first refused write.
  static bool stage(FileProgramStore& store, std::span<const std::uint8_t> bytes) {
    for (std::size_t at = 0; at < bytes.size(); at += kSegmentBytes) {
      if (!store.write_staging(bytes.subspan(at, std::min(kSegmentBytes, bytes.size() - at)))) return false;
    }
    return true;
  }

  fs::path dir;
};

TEST_F(FileProgramStoreTest, AnImageOfManyBuffersIsKeptByteForByteAndExecutable) {
  FileProgramStore store{dir.string()};
  const std::vector<std::uint8_t> image = image_of(3 * 64 * 1024 + 5);
  ASSERT_TRUE(store.open_staging()) << store.last_error();
  ASSERT_TRUE(stage(store, image)) << store.last_error();
  ASSERT_TRUE(store.commit_staging()) << store.last_error();
  EXPECT_FALSE(fs::exists(dir / "staged.part"));
  EXPECT_EQ(read_file(dir / "staged.img"), image);
  EXPECT_EQ(fs::status(dir / "staged.img").permissions() & fs::perms::owner_exec, fs::perms::owner_exec);
}

TEST_F(FileProgramStoreTest, TheDownloadReachesTheFileABufferOf64KiBAtATime) {
  FileProgramStore store{dir.string()};
  const std::vector<std::uint8_t> image = image_of(64 * 1024 + kSegmentBytes);
  const std::span<const std::uint8_t> bytes{image};
  ASSERT_TRUE(store.open_staging());
  ASSERT_TRUE(store.write_staging(bytes.first(64 * 1024 - 1)));
  EXPECT_EQ(fs::file_size(dir / "staged.part"), 0u) << "a byte short of a buffer: nothing written yet";
  ASSERT_TRUE(store.write_staging(bytes.subspan(64 * 1024 - 1, 1)));
  EXPECT_EQ(fs::file_size(dir / "staged.part"), 64u * 1024) << "a whole buffer: written in one go";
  ASSERT_TRUE(store.write_staging(bytes.subspan(64 * 1024)));
  EXPECT_EQ(fs::file_size(dir / "staged.part"), 64u * 1024);
  ASSERT_TRUE(store.commit_staging());
  EXPECT_EQ(read_file(dir / "staged.img"), image);
}

TEST_F(FileProgramStoreTest, ADiscardedDownloadLeavesNothingStagedAndRefusesFurtherWrites) {
  FileProgramStore store{dir.string()};
  const std::vector<std::uint8_t> image = image_of(1000);
  ASSERT_TRUE(store.open_staging());
  ASSERT_TRUE(stage(store, image));
  store.discard_staging();
  EXPECT_FALSE(fs::exists(dir / "staged.part"));
  EXPECT_FALSE(fs::exists(dir / "staged.img"));
  EXPECT_FALSE(store.write_staging(image));
  EXPECT_FALSE(store.commit_staging());
  EXPECT_FALSE(fs::exists(dir / "staged.img"));
}

TEST_F(FileProgramStoreTest, ANewDownloadStartsFromNothingAfterAnUnfinishedOne) {
  FileProgramStore store{dir.string()};
  const std::vector<std::uint8_t> first = image_of(70 * 1024);
  const std::vector<std::uint8_t> second = image_of(100);
  ASSERT_TRUE(store.open_staging());
  ASSERT_TRUE(stage(store, first));
  ASSERT_TRUE(store.open_staging());
  ASSERT_TRUE(stage(store, second));
  ASSERT_TRUE(store.commit_staging());
  EXPECT_EQ(read_file(dir / "staged.img"), second);
}

TEST_F(FileProgramStoreTest, WhatAnEarlierProcessLeftStagedIsRemovedTheRunningImageKept) {
  write_file(dir / "staged.part", "half an image");
  write_file(dir / "staged.img", "an image never started");
  write_file(dir / "running.img", "the running image");
  FileProgramStore store{dir.string()};
  EXPECT_FALSE(fs::exists(dir / "staged.part"));
  EXPECT_FALSE(fs::exists(dir / "staged.img"));
  EXPECT_EQ(read_file(dir / "running.img").size(), std::string("the running image").size());
}

TEST_F(FileProgramStoreTest, PromotionMakesTheStagedImageTheRunningOne) {
  FileProgramStore store{dir.string()};
  const std::vector<std::uint8_t> image = image_of(500);
  write_file(dir / "running.img", "the previous image");
  ASSERT_TRUE(store.open_staging());
  ASSERT_TRUE(stage(store, image));
  ASSERT_TRUE(store.commit_staging());
  EXPECT_EQ(store.promote_staged(), (dir / "running.img").string());
  EXPECT_EQ(read_file(dir / "running.img"), image);
  EXPECT_FALSE(fs::exists(dir / "staged.img"));
  EXPECT_EQ(store.promote_staged(), "") << "nothing staged any more";
  EXPECT_EQ(store.last_error(), "cannot rename " + (dir / "staged.img").string() + ": No such file or directory");
}

TEST_F(FileProgramStoreTest, ADirectoryThatIsGoneIsReportedWithItsCause) {
  FileProgramStore store{(dir / "gone").string()};
  EXPECT_FALSE(store.open_staging());
  EXPECT_EQ(store.last_error(), "cannot create " + (dir / "gone" / "staged.part").string() + ": No such file or directory");
  EXPECT_FALSE(store.write_staging(image_of(7)));
}

TEST_F(FileProgramStoreTest, TheRunningImagesCrcIsTheExecutablesAndStaysTheSame) {
  FileProgramStore store{dir.string()};
  const std::uint32_t crc = store.running_image_crc32();
  EXPECT_NE(crc, 0u);
  EXPECT_EQ(store.running_image_crc32(), crc);
  FileProgramStore another{dir.string()};
  EXPECT_EQ(another.running_image_crc32(), crc) << "the same executable, the same CRC";
}

}  // namespace
}  // namespace linuxhw

// FileParameterStorage: atomic replace, missing/oversized/corrupt files, and the node on top.
#include "FileParameterStorage.hpp"

#include <gtest/gtest.h>
#include <stdlib.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "../../canopen/NodeTestSupport.hpp"

namespace linuxhw {
namespace {

namespace fs = std::filesystem;

std::vector<std::byte> bytes_of(std::string_view text) {
  std::vector<std::byte> out;
  for (char c : text) out.push_back(static_cast<std::byte>(c));
  return out;
}

std::string read_file(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

class FileParameterStorageTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::temp_directory_path() / "fw-params-XXXXXX").string();
    ASSERT_NE(::mkdtemp(pattern.data()), nullptr);
    dir = pattern;
    path = dir / "parameters.bin";
  }
  void TearDown() override { fs::remove_all(dir); }

  fs::path dir;
  fs::path path;
};

TEST_F(FileParameterStorageTest, MissingFileLoadsNothingWithoutError) {
  FileParameterStorage storage(path.string());
  std::array<std::byte, 16> buffer{};
  EXPECT_EQ(storage.load(buffer), 0u);
  EXPECT_TRUE(storage.last_error().empty());
}

TEST_F(FileParameterStorageTest, SaveThenLoadRoundTripsAndLeavesNoTemporaryFile) {
  FileParameterStorage storage(path.string());
  ASSERT_TRUE(storage.save(bytes_of("first image"))) << storage.last_error();
  ASSERT_TRUE(storage.save(bytes_of("second"))) << storage.last_error();
  std::array<std::byte, 32> buffer{};
  const std::size_t size = storage.load(buffer);
  EXPECT_EQ(std::vector<std::byte>(buffer.begin(), buffer.begin() + static_cast<long>(size)),
            bytes_of("second"));
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir)) names.push_back(entry.path().filename());
  EXPECT_EQ(names, std::vector<std::string>{"parameters.bin"});
}

TEST_F(FileParameterStorageTest, CrashBeforeRenameLeavesTheOldFile) {
  FileParameterStorage storage(path.string());
  ASSERT_TRUE(storage.save(bytes_of("old")));
  // What a kill between write and rename leaves behind: a half-written temporary file.
  std::ofstream(path.string() + ".tmp", std::ios::binary) << "ne";
  EXPECT_EQ(read_file(path), "old");
  // The next save simply replaces the leftover, even without a load() in between.
  ASSERT_TRUE(storage.save(bytes_of("new")));
  EXPECT_EQ(read_file(path), "new");
  EXPECT_FALSE(fs::exists(path.string() + ".tmp"));
}

TEST_F(FileParameterStorageTest, LoadRemovesTheTemporaryFileAKilledSaveLeft) {
  FileParameterStorage storage(path.string());
  ASSERT_TRUE(storage.save(bytes_of("old")));
  // A kill between creating the temporary file and renaming it: empty, half or whole image.
  for (const std::string_view leftover : {"", "ne", "new"}) {
    std::ofstream(path.string() + ".tmp", std::ios::binary) << leftover;
    std::array<std::byte, 32> buffer{};
    EXPECT_EQ(storage.load(buffer), 3u) << "leftover '" << leftover << "'";
    EXPECT_TRUE(storage.last_error().empty()) << storage.last_error();
    EXPECT_EQ(read_file(path), "old");
    EXPECT_FALSE(fs::exists(path.string() + ".tmp")) << "leftover '" << leftover << "'";
  }
}

TEST_F(FileParameterStorageTest, LeftoverOfAKilledFirstSaveLoadsNothingAndIsRemoved) {
  std::ofstream(path.string() + ".tmp", std::ios::binary) << "ne";
  FileParameterStorage storage(path.string());
  std::array<std::byte, 32> buffer{};
  EXPECT_EQ(storage.load(buffer), 0u);
  EXPECT_TRUE(storage.last_error().empty()) << storage.last_error();
  EXPECT_TRUE(fs::is_empty(dir));
}

TEST_F(FileParameterStorageTest, FileLargerThanTheBufferLoadsNothing) {
  FileParameterStorage storage(path.string());
  ASSERT_TRUE(storage.save(bytes_of("0123456789")));
  std::array<std::byte, 4> small{};
  EXPECT_EQ(storage.load(small), 0u);
  EXPECT_FALSE(storage.last_error().empty());
  std::array<std::byte, 10> exact{};
  EXPECT_EQ(storage.load(exact), 10u);
}

TEST_F(FileParameterStorageTest, SaveIntoMissingDirectoryFailsAndSaysWhy) {
  FileParameterStorage storage((dir / "no-such-dir" / "p.bin").string());
  EXPECT_FALSE(storage.save(bytes_of("x")));
  EXPECT_NE(storage.last_error().find("cannot create"), std::string::npos) << storage.last_error();
}

class NodeOnFileStorageTest : public FileParameterStorageTest {};

TEST_F(NodeOnFileStorageTest, StoredParametersSurviveARestart) {
  using co::test::FakeBoard;
  const auto field = board::FieldId::velocity_kp;
  const float value = board::info(field).max;
  {
    FileParameterStorage storage(path.string());
    co::MemoryPort port;
    FakeBoard fields;
    co::test::FakeHil hil;
    co::Node node(0x10, port, fields, hil, storage);
    node.start(0);
    fields.values[FakeBoard::index(field)] = value;
    ASSERT_TRUE(node.store_parameters()) << storage.last_error();
  }
  FileParameterStorage storage(path.string());
  co::MemoryPort port;
  FakeBoard fields;
  co::test::FakeHil hil;
  co::Node node(0x10, port, fields, hil, storage);
  node.start(0);
  EXPECT_EQ(node.parameter_load(), co::ParameterLoad::Loaded);
  EXPECT_FLOAT_EQ(fields.values[FakeBoard::index(field)], value);
}

TEST_F(NodeOnFileStorageTest, CorruptFileIsRejectedByTheCrc) {
  using co::test::FakeBoard;
  const auto field = board::FieldId::velocity_kp;
  {
    FileParameterStorage storage(path.string());
    co::MemoryPort port;
    FakeBoard fields;
    co::test::FakeHil hil;
    co::Node node(0x10, port, fields, hil, storage);
    node.start(0);
    fields.values[FakeBoard::index(field)] = board::info(field).max;
    ASSERT_TRUE(node.store_parameters());
  }
  std::string contents = read_file(path);
  contents[contents.size() - 2] ^= 0x40;  // one bit of the last stored value
  std::ofstream(path, std::ios::binary | std::ios::trunc) << contents;

  FileParameterStorage storage(path.string());
  co::MemoryPort port;
  FakeBoard fields;
  co::test::FakeHil hil;
  co::Node node(0x10, port, fields, hil, storage);
  node.start(0);
  EXPECT_EQ(node.parameter_load(), co::ParameterLoad::Rejected);
  EXPECT_FLOAT_EQ(fields.values[FakeBoard::index(field)], board::info(field).default_value);
}

}  // namespace
}  // namespace linuxhw

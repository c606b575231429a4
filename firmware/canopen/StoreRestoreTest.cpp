// Store parameters (0x1010) / restore default parameters (0x1011) and the parameter image.
#include "NodeTestSupport.hpp"
#include "ObjectTables.hpp"

namespace co::test {
namespace {

using board::FieldId;

std::size_t stored_field_count() {
  std::size_t n = 0;
  for (const board::FieldInfo& f : board::kFields) n += f.stored ? 1 : 0;
  return n;
}

class StoreRestoreTest : public NodeTest {
 protected:
  static constexpr FieldId kParameter = FieldId::velocity_kp;
  float stored_value() const { return board::info(kParameter).max; }
  void set_and_store() {
    ASSERT_TRUE(board::info(kParameter).stored);
    ASSERT_NE(stored_value(), board::info(kParameter).default_value);
    ASSERT_EQ(download_float(index_of(kParameter), stored_value()), SdoAbort::None);
    ASSERT_EQ(download(0x1010, 1, Node::kStoreSignature, 4), SdoAbort::None);
  }
};

TEST_F(StoreRestoreTest, ObjectsDescribeSaveOnCommand) {
  EXPECT_EQ(upload(0x1010, 0), 1u);
  EXPECT_EQ(upload(0x1010, 1), 1u);
  EXPECT_EQ(upload(0x1011, 0), 1u);
  EXPECT_EQ(upload(0x1011, 1), 1u);
}

TEST_F(StoreRestoreTest, StoreWritesAValidImageOfTheStoredFieldsOnly) {
  set_and_store();
  EXPECT_EQ(storage.saves, 1u);
  std::size_t count = 0;
  ASSERT_EQ(parameter_image::check(storage.bytes, count), parameter_image::Check::Valid);
  EXPECT_EQ(count, stored_field_count());
  bool found = false;
  for (std::size_t i = 0; i < count; ++i) {
    const auto entry = parameter_image::entry(storage.bytes, i);
    const auto found_field = tables::field_at(entry.index);
    ASSERT_TRUE(found_field.has_value());
    const FieldId field = *found_field;
    ASSERT_TRUE(board::info(field).stored) << "index 0x" << std::hex << entry.index;
    if (field == kParameter) {
      found = true;
      EXPECT_FLOAT_EQ(entry.value, stored_value());
    }
  }
  EXPECT_TRUE(found);
}

TEST_F(StoreRestoreTest, WrongSignatureAbortsAndStoresNothing) {
  EXPECT_EQ(download(0x1010, 1, 0x12345678, 4), SdoAbort::DataCannotBeStored);
  EXPECT_EQ(download(0x1011, 1, Node::kStoreSignature, 4), SdoAbort::DataCannotBeStored);
  EXPECT_EQ(storage.saves, 0u);
}

TEST_F(StoreRestoreTest, StorageFailureAbortsDataCannotBeStored) {
  storage.fail_saves = true;
  EXPECT_EQ(download(0x1010, 1, Node::kStoreSignature, 4), SdoAbort::DataCannotBeStored);
}

TEST_F(StoreRestoreTest, StoredValuesAreLoadedAtStartUp) {
  set_and_store();
  MemoryPort port2;
  FakeBoard fields2;
  FakeHil hil2;
  Node restarted(kNodeId, port2, fields2, hil2, storage);
  restarted.start(0);
  EXPECT_EQ(restarted.parameter_load(), ParameterLoad::Loaded);
  EXPECT_FLOAT_EQ(fields2.values[FakeBoard::index(kParameter)], stored_value());
}

TEST_F(StoreRestoreTest, EmptyStorageLeavesDefaults) {
  EXPECT_EQ(node.parameter_load(), ParameterLoad::NothingStored);
}

TEST_F(StoreRestoreTest, CorruptImageIsRejectedAtStartUp) {
  set_and_store();
  for (std::size_t byte : {std::size_t{0}, std::size_t{6}, std::size_t{9}, storage.bytes.size() - 1}) {
    MemoryStorage corrupt;
    corrupt.bytes = storage.bytes;
    corrupt.bytes[byte] ^= std::byte{0x01};
    MemoryPort port2;
    FakeBoard fields2;
    FakeHil hil2;
    Node restarted(kNodeId, port2, fields2, hil2, corrupt);
    restarted.start(0);
    EXPECT_EQ(restarted.parameter_load(), ParameterLoad::Rejected) << "flipped byte " << byte;
    EXPECT_EQ(fields2.writes[FakeBoard::index(kParameter)], 0u);
  }
}

TEST_F(StoreRestoreTest, TruncatedImageIsRejected) {
  set_and_store();
  storage.bytes.pop_back();
  std::size_t count = 0;
  EXPECT_EQ(parameter_image::check(storage.bytes, count), parameter_image::Check::Corrupt);
}

TEST_F(StoreRestoreTest, RestoreDefaultsWritesDefaultsBackAndStoresThem) {
  set_and_store();
  ASSERT_EQ(download(0x1011, 1, Node::kRestoreSignature, 4), SdoAbort::None);
  EXPECT_FLOAT_EQ(fields.values[FakeBoard::index(kParameter)],
                  board::info(kParameter).default_value);
  MemoryPort port2;
  FakeBoard fields2;
  FakeHil hil2;
  fields2.values[FakeBoard::index(kParameter)] = -1.0f;  // anything but the default
  Node restarted(kNodeId, port2, fields2, hil2, storage);
  restarted.start(0);
  EXPECT_FLOAT_EQ(fields2.values[FakeBoard::index(kParameter)],
                  board::info(kParameter).default_value);
}

TEST_F(StoreRestoreTest, RestoreRefusedByTheBoardAborts) {
  fields.refuse[FakeBoard::index(kParameter)] = true;
  EXPECT_EQ(download(0x1011, 1, Node::kRestoreSignature, 4), SdoAbort::DataCannotBeStored);
}

TEST(ParameterImageTest, Crc32MatchesTheStandardCheckValue) {
  const char* text = "123456789";
  std::array<std::byte, 9> bytes{};
  for (std::size_t i = 0; i < 9; ++i) bytes[i] = static_cast<std::byte>(text[i]);
  EXPECT_EQ(parameter_image::crc32(bytes), 0xCBF4'3926u);
}

}  // namespace
}  // namespace co::test

// Store parameters (0x1010) / restore default parameters (0x1011) and the parameter image.
#include <bit>
#include <vector>

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

TEST_F(StoreRestoreTest, ObjectsDescribeSaveOnCommandForAllCommunicationAndApplication) {
  for (std::uint16_t index : {std::uint16_t{0x1010}, std::uint16_t{0x1011}}) {
    EXPECT_EQ(upload(index, 0), 3u);
    for (std::uint8_t sub = 1; sub <= 3; ++sub) EXPECT_EQ(upload(index, sub), 1u) << sub;
    EXPECT_EQ(upload_abort(index, 4), SdoAbort::SubIndexDoesNotExist);
  }
}

TEST_F(StoreRestoreTest, StoreAllWritesStoredFieldsAndCommunicationParameters) {
  set_and_store();
  EXPECT_EQ(storage.saves, 1u);
  std::size_t count = 0;
  ASSERT_EQ(parameter_image::check(storage.bytes, count), parameter_image::Check::Valid);
  std::size_t fields_stored = 0;
  bool found = false;
  bool heartbeat = false;
  for (std::size_t i = 0; i < count; ++i) {
    const auto entry = parameter_image::entry(storage.bytes, i);
    if (parameter_image::is_communication(entry.index)) {
      heartbeat = heartbeat || entry.index == 0x1017;
      continue;
    }
    ++fields_stored;
    const auto found_field = tables::field_at(entry.index, entry.sub);
    ASSERT_TRUE(found_field.has_value());
    const FieldId field = *found_field;
    ASSERT_TRUE(board::info(field).stored) << "index 0x" << std::hex << entry.index;
    if (field == kParameter) {
      found = true;
      EXPECT_FLOAT_EQ(std::bit_cast<float>(entry.raw), stored_value());
    }
  }
  EXPECT_EQ(fields_stored, stored_field_count());
  EXPECT_TRUE(found);
  EXPECT_TRUE(heartbeat);
}

// The finding: "save all" then reset node lost 0x1005 and 0x1017. Exact frames.
TEST_F(StoreRestoreTest, SaveAllThenResetNodeKeepsCommunicationParameters) {
  EXPECT_EQ(sdo({0x23, 0x05, 0x10, 0x00, 0x81, 0x00, 0x00, 0x00}),
            (std::array<std::uint8_t, 8>{0x60, 0x05, 0x10, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(sdo({0x2B, 0x17, 0x10, 0x00, 0xFA, 0x00, 0, 0}),
            (std::array<std::uint8_t, 8>{0x60, 0x17, 0x10, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(sdo({0x23, 0x10, 0x10, 0x01, 's', 'a', 'v', 'e'}),
            (std::array<std::uint8_t, 8>{0x60, 0x10, 0x10, 0x01, 0, 0, 0, 0}));
  nmt(NmtCommand::ResetNode);
  EXPECT_EQ(next_sent(), make_frame(kHeartbeat, {0x00})) << "boot-up";
  EXPECT_EQ(sdo({0x40, 0x05, 0x10, 0x00, 0, 0, 0, 0}),
            (std::array<std::uint8_t, 8>{0x43, 0x05, 0x10, 0x00, 0x81, 0x00, 0x00, 0x00}));
  EXPECT_EQ(sdo({0x40, 0x17, 0x10, 0x00, 0, 0, 0, 0}),
            (std::array<std::uint8_t, 8>{0x4B, 0x17, 0x10, 0x00, 0xFA, 0x00, 0, 0}));
  // The stored SYNC COB-ID is in force, not only readable.
  nmt(NmtCommand::Start);
  EXPECT_TRUE(receive(0x081, {}).sync);  // protocol-literal: the stored SYNC id
  EXPECT_FALSE(receive(cia301::kSyncCobId, {}).sync);
}

TEST_F(StoreRestoreTest, StoredCommunicationParametersSurviveResetCommunicationAndPowerCycle) {
  ASSERT_EQ(download(0x1017, 0, 250, 2), SdoAbort::None);
  ASSERT_EQ(download(0x1019, 0, 16, 1), SdoAbort::None);
  ASSERT_EQ(download(0x1010, 2, Node::kStoreSignature, 4), SdoAbort::None);
  ASSERT_EQ(download(0x1017, 0, 0, 2), SdoAbort::None);
  nmt(NmtCommand::ResetCommunication);
  all_sent();
  EXPECT_EQ(upload(0x1017, 0), 250u);
  EXPECT_EQ(upload(0x1019, 0), 16u);
  MemoryPort port2;
  FakeBoard fields2;
  FakeHil hil2;
  Node restarted(kNodeId, port2, fields2, hil2, storage);
  restarted.start(0);
  EXPECT_EQ(restarted.heartbeat_period_ms(), 250u);
}

TEST_F(StoreRestoreTest, StoredPdoMappingIsInForceAfterReset) {
  // TPDO1: motor_velocity alone, every 2nd SYNC.
  const std::uint32_t cob_id = 0x4000'0000u | (cia301::cob_id(cia301::FunctionCode::Tpdo1, kNodeId));
  const std::uint32_t entry = (std::uint32_t{index_of(FieldId::motor_velocity)} << 16) | 32;
  ASSERT_EQ(download(0x1800, 1, cob_id | 0x8000'0000u, 4), SdoAbort::None);
  ASSERT_EQ(download(0x1800, 2, 2, 1), SdoAbort::None);
  ASSERT_EQ(download(0x1A00, 0, 0, 1), SdoAbort::None);
  ASSERT_EQ(download(0x1A00, 1, entry, 4), SdoAbort::None);
  ASSERT_EQ(download(0x1A00, 0, 1, 1), SdoAbort::None);
  ASSERT_EQ(download(0x1800, 1, cob_id, 4), SdoAbort::None);
  ASSERT_EQ(download(0x1010, 1, Node::kStoreSignature, 4), SdoAbort::None);
  nmt(NmtCommand::ResetNode);
  all_sent();
  EXPECT_EQ(upload(0x1800, 1), cob_id);
  EXPECT_EQ(upload(0x1800, 2), 2u);
  EXPECT_EQ(upload(0x1A00, 0), 1u);
  EXPECT_EQ(upload(0x1A00, 1), entry);
  for (std::uint16_t n = 1; n < board::kTpdoCount; ++n) {  // only TPDO1 on the bus
    const auto comm = static_cast<std::uint16_t>(0x1800 + n);
    ASSERT_EQ(download(comm, 1, upload(comm, 1) | 0x8000'0000u, 4), SdoAbort::None);
  }
  fields.values[FakeBoard::index(FieldId::motor_velocity)] = 1.5f;
  nmt(NmtCommand::Start);
  sync();
  EXPECT_TRUE(all_sent().empty()) << "type 2: not at the first SYNC";
  sync();
  const auto v = le32(float_bits(1.5f));
  EXPECT_EQ(next_sent(), make_frame(cia301::cob_id(cia301::FunctionCode::Tpdo1, kNodeId), {v[0], v[1], v[2], v[3]}));
}

TEST_F(StoreRestoreTest, StoredPdoTheFirmwareNoLongerAcceptsFallsBackToItsDefault) {
  // An image from another firmware: TPDO1 mapped to an object that does not exist here.
  const std::array<parameter_image::StoredValue, 3> values = {{
      {0x1A00, 0, 1},
      {0x1A00, 1, 0x2FFF'0020u},
      {0x1017, 0, 300},
  }};
  storage.bytes.resize(parameter_image::kCapacity);
  std::array<std::byte, parameter_image::kCapacity> image{};
  storage.bytes.assign(image.begin(), image.begin() + parameter_image::encode(values, image));
  nmt(NmtCommand::ResetCommunication);
  all_sent();
  const board::PdoDefault& d = board::kDefaultTpdos[0];
  EXPECT_EQ(upload(0x1A00, 0), d.count);
  EXPECT_EQ(upload(0x1800, 1) & 0x8000'0000u, d.enabled ? 0u : 0x8000'0000u);
  EXPECT_EQ(upload(0x1017, 0), 300u) << "the other stored values still apply";
}

TEST_F(StoreRestoreTest, StoreOneGroupKeepsWhatIsStoredForTheOther) {
  set_and_store();                                              // all: velocity_kp = max
  ASSERT_EQ(download_float(index_of(kParameter), board::info(kParameter).default_value),
            SdoAbort::None);
  ASSERT_EQ(download(0x1017, 0, 300, 2), SdoAbort::None);
  ASSERT_EQ(download(0x1010, 2, Node::kStoreSignature, 4), SdoAbort::None);  // communication
  MemoryPort port2;
  FakeBoard fields2;
  FakeHil hil2;
  Node restarted(kNodeId, port2, fields2, hil2, storage);
  restarted.start(0);
  EXPECT_FLOAT_EQ(fields2.values[FakeBoard::index(kParameter)], stored_value());
  EXPECT_EQ(restarted.heartbeat_period_ms(), 300u);
}

TEST_F(StoreRestoreTest, StoreApplicationDoesNotStoreCommunication) {
  ASSERT_EQ(download(0x1017, 0, 300, 2), SdoAbort::None);
  ASSERT_EQ(download(0x1010, 3, Node::kStoreSignature, 4), SdoAbort::None);
  nmt(NmtCommand::ResetNode);
  all_sent();
  EXPECT_EQ(upload(0x1017, 0), board::kNode.heartbeat_ms);
}

TEST_F(StoreRestoreTest, RestoredCommunicationDefaultsTakeEffectAtTheNextReset) {
  ASSERT_EQ(download(0x1017, 0, 300, 2), SdoAbort::None);
  ASSERT_EQ(download(0x1010, 1, Node::kStoreSignature, 4), SdoAbort::None);
  ASSERT_EQ(download(0x1011, 2, Node::kRestoreSignature, 4), SdoAbort::None);
  EXPECT_EQ(upload(0x1017, 0), 300u) << "CiA 301: restored values are valid after a reset";
  nmt(NmtCommand::ResetCommunication);
  all_sent();
  EXPECT_EQ(upload(0x1017, 0), board::kNode.heartbeat_ms);
}

TEST_F(StoreRestoreTest, VerifyConfigurationIsStoredAndClearedByRestore) {
  EXPECT_EQ(upload(0x1020, 0), 2u);
  EXPECT_EQ(upload(0x1020, 1), 0u);
  ASSERT_EQ(download(0x1020, 1, 15'000, 4), SdoAbort::None);  // days since 1984-01-01
  ASSERT_EQ(download(0x1020, 2, 43'200'000, 4), SdoAbort::None);  // ms after midnight
  ASSERT_EQ(download(0x1010, 1, Node::kStoreSignature, 4), SdoAbort::None);
  nmt(NmtCommand::ResetNode);
  all_sent();
  EXPECT_EQ(upload(0x1020, 1), 15'000u);
  EXPECT_EQ(upload(0x1020, 2), 43'200'000u);
  ASSERT_EQ(download(0x1011, 3, Node::kRestoreSignature, 4), SdoAbort::None);
  EXPECT_EQ(upload(0x1020, 1), 0u) << "the boot-up configuration changed";
  nmt(NmtCommand::ResetNode);
  all_sent();
  EXPECT_EQ(upload(0x1020, 1), 0u);
}

TEST_F(StoreRestoreTest, ImageOfTheFieldsOnlyFormatStillLoads) {
  // Format 1: header, then u16 index + f32 per stored field; CRC over all but bytes 8..11.
  std::vector<std::byte> image(12 + 6);
  auto put = [&](std::size_t at, std::uint32_t v, std::size_t n) {
    for (std::size_t i = 0; i < n; ++i) image[at + i] = static_cast<std::byte>(v >> (8 * i));
  };
  put(0, parameter_image::kMagic, 4);
  put(4, 1, 2);
  put(6, 1, 2);
  put(12, index_of(kParameter), 2);
  put(14, float_bits(stored_value()), 4);
  std::vector<std::byte> covered(image.begin(), image.begin() + 8);
  covered.insert(covered.end(), image.begin() + 12, image.end());
  put(8, parameter_image::crc32(covered), 4);
  storage.bytes = image;
  MemoryPort port2;
  FakeBoard fields2;
  FakeHil hil2;
  Node restarted(kNodeId, port2, fields2, hil2, storage);
  restarted.start(0);
  EXPECT_EQ(restarted.parameter_load(), ParameterLoad::Loaded);
  EXPECT_FLOAT_EQ(fields2.values[FakeBoard::index(kParameter)], stored_value());
}

TEST_F(StoreRestoreTest, WrongSignatureAbortsAndStoresNothing) {
  for (std::uint8_t sub = 1; sub <= 3; ++sub) {
    EXPECT_EQ(download(0x1010, sub, 0x12345678, 4), SdoAbort::DataCannotBeStored);
    EXPECT_EQ(download(0x1011, sub, Node::kStoreSignature, 4), SdoAbort::DataCannotBeStored);
  }
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

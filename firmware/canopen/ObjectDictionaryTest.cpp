// The object dictionary the node serves is the one the generated EDS describes, both ways
// (CiA 306: the EDS is the device's description; a certification lab checks it against the
// device): every (index, sub-index) the EDS lists answers an SDO upload with a value of the
// listed size, nothing else answers, and every object reads its EDS DefaultValue at power-on
// and again after reset node.
#include <fstream>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <utility>

#include "NodeTestSupport.hpp"
#include "ObjectTables.hpp"

namespace co::test {
namespace {

using Address = std::pair<std::uint16_t, std::uint8_t>;

struct EdsEntry {
  std::uint16_t data_type = 0;
  std::string default_value;
  bool write_only = false;  // AccessType=wo: an upload is refused (0x06010001), a download is not
};

std::string hex(Address a) {
  std::ostringstream out;
  out << "0x" << std::hex << a.first << ":" << int{a.second};
  return out.str();
}

// The (index, sub-index) objects of an EDS: [XXXX] sections of plain variables and
// [XXXXsubN] sections of arrays and records. Only the keys this test compares are kept.
std::map<Address, EdsEntry> read_eds(const std::string& path) {
  std::ifstream file(path);
  EXPECT_TRUE(file.good()) << "cannot read " << path;
  std::map<Address, EdsEntry> entries;
  std::optional<Address> current;
  bool variable = false;
  std::string line;
  while (std::getline(file, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == ';') continue;
    if (line[0] == '[') {
      const std::string name = line.substr(1, line.find(']') - 1);
      current.reset();
      variable = false;
      if (name.size() < 4 || name.find_first_not_of("0123456789ABCDEFabcdef") < 4) continue;
      const auto index = static_cast<std::uint16_t>(std::stoul(name.substr(0, 4), nullptr, 16));
      if (name.size() == 4) {
        current = Address{index, 0};
        variable = true;  // decided by ObjectType below
      } else if (name.compare(4, 3, "sub") == 0) {
        current = Address{index, static_cast<std::uint8_t>(std::stoul(name.substr(7), nullptr, 16))};
        entries[*current];
      }
      continue;
    }
    if (!current) continue;
    const auto equals = line.find('=');
    if (equals == std::string::npos) continue;
    const std::string key = line.substr(0, equals);
    const std::string value = line.substr(equals + 1);
    if (key == "ObjectType" && variable && std::stoul(value, nullptr, 0) == 0x7) entries[*current];
    if (!entries.contains(*current)) continue;
    if (key == "DataType") entries[*current].data_type = static_cast<std::uint16_t>(std::stoul(value, nullptr, 0));
    if (key == "DefaultValue") entries[*current].default_value = value;
    if (key == "AccessType") entries[*current].write_only = value == "wo";
  }
  return entries;
}

std::size_t size_of_eds_type(std::uint16_t data_type) {
  switch (data_type) {
    case 0x0001: case 0x0002: case 0x0005: return 1;  // BOOLEAN, INTEGER8, UNSIGNED8
    case 0x0003: case 0x0006: return 2;               // INTEGER16, UNSIGNED16
    case 0x0004: case 0x0007: case 0x0008: return 4;  // INTEGER32, UNSIGNED32, REAL32
    default: return 0;                                // VISIBLE_STRING: segmented
  }
}

class ObjectDictionaryTest : public NodeTest {
 protected:
  void SetUp() override {
    NodeTest::SetUp();
    eds = read_eds(BOARD_EDS_PATH);
    ASSERT_GT(eds.size(), 100u) << BOARD_EDS_PATH;
  }

  // The SDO upload answer for one object, from a fresh request.
  std::array<std::uint8_t, 8> upload_response(Address a) {
    const auto response = sdo({0x40, static_cast<std::uint8_t>(a.first),
                               static_cast<std::uint8_t>(a.first >> 8), a.second, 0, 0, 0, 0});
    if (response[0] == 0x41) {  // end the segmented upload: a client abort gets no answer
      receive(kSdoRx, {0x80, static_cast<std::uint8_t>(a.first), static_cast<std::uint8_t>(a.first >> 8),
                       a.second, 0, 0, 0, 0});
      EXPECT_TRUE(all_sent().empty());
    }
    return response;
  }
  static bool answered(const std::array<std::uint8_t, 8>& response) { return response[0] != 0x80; }
  // Answered, or refused as write-only: the object exists for SDO either way.
  static bool exists_for_sdo(const std::array<std::uint8_t, 8>& response) {
    return answered(response) ||
           tables::get_le(std::span<const std::uint8_t>(response).subspan(4, 4)) == to_code(SdoAbort::WriteOnly);
  }

  // The value the EDS says the object has at power-on, for the node under test.
  static std::optional<std::uint32_t> eds_default(const EdsEntry& entry) {
    std::string text = entry.default_value;
    std::uint32_t offset = 0;
    if (text.rfind("$NODEID+", 0) == 0) {
      offset = kNodeId;
      text = text.substr(8);
    }
    if (text.empty() || entry.data_type == 0x0009) return std::nullopt;
    if (entry.data_type == 0x0008) return float_bits(std::stof(text));
    return static_cast<std::uint32_t>(std::stoll(text, nullptr, 0)) + offset;
  }

  void expect_every_object_at_its_eds_default(const char* when) {
    for (const auto& [address, entry] : eds) {
      if (address == Address{0x1018, 4}) continue;  // serial number: per board, EDS says 0
      const auto expected = eds_default(entry);
      if (!expected) continue;
      const auto response = upload_response(address);
      ASSERT_TRUE(answered(response)) << hex(address);
      const std::size_t size = 4 - ((response[0] >> 2) & 3u);
      const auto value = static_cast<std::uint32_t>(tables::get_le(std::span<const std::uint8_t>(response).subspan(4, size)));
      const std::uint32_t mask = size == 4 ? 0xFFFF'FFFFu : (1u << (8 * size)) - 1u;
      EXPECT_EQ(value, *expected & mask) << hex(address) << " " << when << ": EDS DefaultValue "
                                         << entry.default_value;
    }
  }

  std::map<Address, EdsEntry> eds;
};

TEST_F(ObjectDictionaryTest, EveryObjectInTheEdsAnswersWithItsListedSize) {
  for (const auto& [address, entry] : eds) {
    const auto response = upload_response(address);
    if (entry.write_only) {
      EXPECT_TRUE(exists_for_sdo(response) && !answered(response)) << hex(address) << ": write-only in the EDS";
      continue;
    }
    ASSERT_TRUE(answered(response)) << hex(address) << " is in the EDS but the node aborts 0x"
                                    << std::hex << tables::get_le(std::span<const std::uint8_t>(response).subspan(4, 4));
    const std::size_t expected = size_of_eds_type(entry.data_type);
    if (expected == 0) {
      EXPECT_EQ(response[0], 0x41) << hex(address) << ": a string is a segmented upload";
      continue;
    }
    ASSERT_EQ(response[0] & 0xF3, 0x43) << hex(address) << ": expedited with size";
    EXPECT_EQ(4 - ((response[0] >> 2) & 3u), expected) << hex(address);
  }
}

TEST_F(ObjectDictionaryTest, EveryObjectTheNodeAnswersIsInTheEds) {
  std::set<std::uint16_t> eds_indices;
  for (const auto& [address, entry] : eds) eds_indices.insert(address.first);
  for (std::uint32_t index = 0x1000; index <= 0x5FFF; ++index) {
    const auto i = static_cast<std::uint16_t>(index);
    const auto response = upload_response({i, 0});
    const bool exists = answered(response) ||
                        tables::get_le(std::span<const std::uint8_t>(response).subspan(4, 4)) !=
                            to_code(SdoAbort::ObjectDoesNotExist);
    ASSERT_EQ(exists, eds_indices.contains(i)) << "object 0x" << std::hex << index
                                               << (exists ? " answers but is not in the EDS"
                                                          : " is in the EDS but does not exist");
    if (!exists) continue;
    for (std::uint32_t sub = 0; sub <= 0xFF; ++sub) {
      const Address a{i, static_cast<std::uint8_t>(sub)};
      EXPECT_EQ(exists_for_sdo(upload_response(a)), eds.contains(a)) << hex(a);
    }
  }
}

TEST_F(ObjectDictionaryTest, EveryObjectReadsItsEdsDefaultAtPowerOn) {
  // The fixture switched the heartbeat off (its only write); put it back.
  ASSERT_EQ(download(0x1017, 0, board::kNode.heartbeat_ms, 2), SdoAbort::None);
  expect_every_object_at_its_eds_default("at power-on");
}

TEST_F(ObjectDictionaryTest, EveryObjectReadsItsEdsDefaultAfterResetNode) {
  // One object of each kind away from its default: communication, PDO, command, HIL input.
  ASSERT_EQ(download(0x1005, 0, 0x81, 4), SdoAbort::None);
  ASSERT_EQ(download(0x1019, 0, 8, 1), SdoAbort::None);
  ASSERT_EQ(download(HeartbeatConsumer::kIndex, 1, 0x0001'0096, 4), SdoAbort::None);
  ASSERT_EQ(download(0x1020, 1, 1234, 4), SdoAbort::None);
  ASSERT_EQ(download(0x1800, 2, 7, 1), SdoAbort::None);
  ASSERT_EQ(download_float(index_of(board::FieldId::velocity_setpoint), 2.5f), SdoAbort::None);
  ASSERT_EQ(download(0x3001, 0, 4321, 2), SdoAbort::None);
  node.report_emcy(emcy::over_temperature(board::FieldId::winding_temperature));
  nmt(NmtCommand::ResetNode);
  all_sent();
  expect_every_object_at_its_eds_default("after reset node");
}


TEST_F(ObjectDictionaryTest, AnArrayOfFieldsServesItsCountAndEachMemberBySubIndex) {
  ASSERT_FALSE(board::kFieldArrays.empty());
  for (const board::FieldArrayInfo& array : board::kFieldArrays) {
    EXPECT_EQ(upload(array.index, 0), array.count) << array.name;
    EXPECT_EQ(download(array.index, 0, array.count, 1), SdoAbort::ReadOnly) << array.name;
    for (std::uint8_t sub = 1; sub <= array.count; ++sub) {
      const auto member = tables::field_at(array.index, sub);
      ASSERT_TRUE(member.has_value()) << array.name << " sub " << int{sub};
      const board::FieldInfo& field = board::info(*member);
      EXPECT_EQ(upload(array.index, sub), tables::field_raw(field, field.default_value)) << field.name;
      const float value = field.max;  // every member is rw here: a parameter
      ASSERT_EQ(download(array.index, sub, tables::field_raw(field, value), tables::size_of(field.type)),
                SdoAbort::None) << field.name;
      EXPECT_EQ(fields.read(*member), value) << field.name;
      EXPECT_EQ(upload(array.index, sub), tables::field_raw(field, value)) << field.name;
    }
    const auto past = static_cast<std::uint8_t>(array.count + 1);
    EXPECT_EQ(upload_abort(array.index, past), SdoAbort::SubIndexDoesNotExist) << array.name;
    EXPECT_EQ(download(array.index, past, 0, 4), SdoAbort::SubIndexDoesNotExist) << array.name;
  }
}

}  // namespace
}  // namespace co::test

// C++ and Python agree on every field, enum value, flag bit and EMCY code: the generated header
// must equal field_vectors.csv and value_vectors.csv, which the generator writes straight from
// the parsed board.toml.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "board/fields.hpp"

namespace {

struct CsvRow {
  std::string name, index, unit, kind, access, min, max, default_value, stored;
};

// The cells of a CSV line without quoting (the vectors quote nothing), empty ones included.
std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> cells;
  std::size_t start = 0;
  for (std::size_t comma = line.find(','); comma != std::string::npos; comma = line.find(',', start)) {
    cells.push_back(line.substr(start, comma - start));
    start = comma + 1;
  }
  cells.push_back(line.substr(start));
  return cells;
}

// Rows of field_vectors.csv without the header line; fails the test on a malformed row.
std::vector<CsvRow> read_rows() {
  std::ifstream file(BOARD_FIELD_VECTORS_CSV);
  EXPECT_TRUE(file.is_open()) << "cannot open " << BOARD_FIELD_VECTORS_CSV;
  std::vector<CsvRow> rows;
  std::string line;
  std::getline(file, line);
  EXPECT_EQ(line, "name,index,unit,kind,access,min,max,default,stored");
  while (std::getline(file, line)) {
    const auto cells = split(line);
    EXPECT_EQ(cells.size(), 9U) << "malformed row: " << line;
    if (cells.size() != 9U) continue;
    rows.push_back({cells[0], cells[1], cells[2], cells[3], cells[4], cells[5], cells[6],
                    cells[7], cells[8]});
  }
  return rows;
}

std::optional<board::Kind> parse_kind(std::string_view text) {
  if (text == "sensor") return board::Kind::Sensor;
  if (text == "virtual_sensor") return board::Kind::VirtualSensor;
  if (text == "module") return board::Kind::Module;
  if (text == "actuator") return board::Kind::Actuator;
  if (text == "command") return board::Kind::Command;
  if (text == "parameter") return board::Kind::Parameter;
  return std::nullopt;
}

std::optional<board::Access> parse_access(std::string_view text) {
  if (text == "ro") return board::Access::ReadOnly;
  if (text == "rw") return board::Access::ReadWrite;
  return std::nullopt;
}

// strtof rounds the decimal text exactly as the compiler rounds the header's literal.
float parse_float(const std::string& text) { return std::strtof(text.c_str(), nullptr); }

TEST(FieldTable, HasOneCsvRowPerField) { EXPECT_EQ(read_rows().size(), board::kFieldCount); }

TEST(FieldTable, EveryFieldMatchesThePythonTable) {
  const auto rows = read_rows();
  ASSERT_EQ(rows.size(), board::kFieldCount);
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const CsvRow& row = rows[i];
    const board::FieldInfo& field = board::kFields[i];
    SCOPED_TRACE("field " + row.name);
    EXPECT_EQ(field.name, row.name);
    EXPECT_EQ(field.index, std::stoul(row.index, nullptr, 16));
    EXPECT_EQ(field.unit, row.unit);
    EXPECT_EQ(std::optional(field.kind), parse_kind(row.kind));
    EXPECT_EQ(std::optional(field.access), parse_access(row.access));
    EXPECT_EQ(field.min, parse_float(row.min));
    EXPECT_EQ(field.max, parse_float(row.max));
    EXPECT_EQ(field.default_value, parse_float(row.default_value));
    EXPECT_EQ(field.stored, row.stored == "1");
  }
}

TEST(FieldTable, InfoLooksUpByFieldId) {
  for (std::size_t i = 0; i < board::kFieldCount; ++i) {
    const auto id = static_cast<board::FieldId>(i);
    EXPECT_EQ(&board::info(id), &board::kFields[i]);
  }
}

TEST(FieldTable, IndicesAreUniqueAndInTheManufacturerRange) {
  std::set<std::pair<std::uint16_t, std::uint8_t>> seen;
  for (const auto& field : board::kFields) {
    // A board field (REAL32) in the manufacturer range; a device profile's object (CiA 402:
    // an integer type) in the profile range.
    if (field.type == board::DataType::Real32) {
      EXPECT_GE(field.index, 0x2000U) << field.name;
      EXPECT_LE(field.index, 0x5FFFU) << field.name;
    } else {
      EXPECT_GE(field.index, 0x6000U) << field.name;
      EXPECT_LE(field.index, 0x9FFFU) << field.name;
    }
    EXPECT_TRUE(seen.insert({field.index, field.subindex}).second) << "duplicate index of " << field.name;
    // A member of an ARRAY (sub 1..n) shares its index with the others, never with a plain object.
    const bool in_array = std::any_of(board::kFieldArrays.begin(), board::kFieldArrays.end(),
                                      [&](const board::FieldArrayInfo& a) { return a.index == field.index; });
    EXPECT_EQ(in_array, field.subindex != 0) << field.name;
  }
  for (const auto& io : board::kHilInputs) EXPECT_TRUE(seen.insert({io.index, 0}).second) << io.name;
  for (const auto& io : board::kHilOutputs) EXPECT_TRUE(seen.insert({io.index, 0}).second) << io.name;
}

TEST(FieldTable, DefaultPdosFitInOneFrame) {
  auto check = [](const board::PdoDefault& pdo) {
    unsigned bits = 0;
    for (std::size_t i = 0; i < pdo.count; ++i) bits += pdo.entries[i].bits;
    EXPECT_LE(bits, 64U) << "PDO " << pdo.number;
    EXPECT_LE(pdo.count, pdo.entries.size());
  };
  for (const auto& pdo : board::kDefaultRpdos) check(pdo);
  for (const auto& pdo : board::kDefaultTpdos) check(pdo);
}

// ---------------------------------------------------------------------------
// Enum values, flag bits and EMCY codes (value_vectors.csv)
// ---------------------------------------------------------------------------

struct ValueRow {
  std::string kind, set, name, number, emcy, register_bit, about;
};

std::vector<ValueRow> read_value_rows(std::string_view kind) {
  std::ifstream file(BOARD_VALUE_VECTORS_CSV);
  EXPECT_TRUE(file.is_open()) << "cannot open " << BOARD_VALUE_VECTORS_CSV;
  std::vector<ValueRow> rows;
  std::string line;
  std::getline(file, line);
  EXPECT_EQ(line, "kind,set,name,number,emcy,register_bit,about");
  while (std::getline(file, line)) {
    const auto cells = split(line);
    EXPECT_EQ(cells.size(), 7U) << "malformed row: " << line;
    if (cells.size() != 7U || cells[0] != kind) continue;
    rows.push_back({cells[0], cells[1], cells[2], cells[3], cells[4], cells[5], cells[6]});
  }
  return rows;
}

// The rows of each enum or bitset, by its name, in table order.
std::map<std::string, std::vector<ValueRow>, std::less<>> rows_by_set(std::string_view kind) {
  std::map<std::string, std::vector<ValueRow>, std::less<>> sets;
  for (ValueRow& row : read_value_rows(kind)) sets[row.set].push_back(std::move(row));
  return sets;
}

std::set<std::string, std::less<>> keys(const std::map<std::string, std::vector<ValueRow>, std::less<>>& sets) {
  std::set<std::string, std::less<>> names;
  for (const auto& [name, rows] : sets) names.insert(name);
  return names;
}

TEST(ValueTable, EveryEmcyCodeMatchesThePythonTable) {
  const auto rows = read_value_rows("emcy");
  ASSERT_EQ(rows.size(), board::kEmcyCount);
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const board::EmcyInfo& emcy = board::info(static_cast<board::EmcyId>(i));
    SCOPED_TRACE("emcy " + rows[i].name);
    EXPECT_EQ(emcy.name, rows[i].name);
    EXPECT_EQ(emcy.code, std::stoul(rows[i].number, nullptr, 16));
    EXPECT_EQ(emcy.register_bit, std::stoul(rows[i].register_bit, nullptr, 16));
  }
}

TEST(ValueTable, EmcyCodesAreUniqueAndSetOneRegisterBit) {
  std::set<std::uint16_t> codes;
  for (const board::EmcyInfo& emcy : board::kEmcyCodes) {
    EXPECT_TRUE(codes.insert(emcy.code).second) << "duplicate code of " << emcy.name;
    EXPECT_NE(emcy.code, 0x0000) << emcy.name << ": 0x0000 is the error reset";
    EXPECT_EQ(std::popcount(emcy.register_bit), 1) << emcy.name;
  }
}

TEST(ValueTable, EveryEnumValueMatchesThePythonTable) {
  const auto sets = rows_by_set("enum");
  std::set<std::string, std::less<>> seen;
  board::for_each_enum([&](std::string_view set, const auto& values) {
    SCOPED_TRACE("enum " + std::string(set));
    seen.insert(std::string(set));
    const auto found = sets.find(set);
    ASSERT_NE(found, sets.end()) << "not in the Python table";
    const std::vector<ValueRow>& rows = found->second;
    ASSERT_EQ(values.size(), rows.size());
    for (std::size_t i = 0; i < rows.size(); ++i) {
      const float number = std::stof(rows[i].number);
      EXPECT_EQ(to_string(values[i]), rows[i].name);
      EXPECT_EQ(to_value(values[i]), number) << rows[i].name;
      EXPECT_EQ(board::from_value(values, number), std::optional(values[i])) << rows[i].name;
    }
  });
  EXPECT_EQ(seen, keys(sets)) << "the header and the Python table list different enums";
}

TEST(ValueTable, FromValueTakesOnlyAnExactValue) {
  board::for_each_enum([](std::string_view set, const auto& values) {
    SCOPED_TRACE("enum " + std::string(set));
    for (const auto value : values) {
      const float number = to_value(value);
      EXPECT_FALSE(board::from_value(values, std::nextafter(number, 1e9F)).has_value()) << to_string(value);
      EXPECT_FALSE(board::from_value(values, number + 0.5F).has_value()) << to_string(value);
    }
    EXPECT_FALSE(board::from_value(values, std::numeric_limits<float>::quiet_NaN()).has_value());
    EXPECT_FALSE(board::from_value(values, std::numeric_limits<float>::infinity()).has_value());
  });
}

// The joint's named enums (this file also checks the head's table, which has none of them).
#ifdef BOARD_TABLE_IS_JOINT
TEST(ValueTable, NamedFromValueTakesOnlyAnExactValue) {
  EXPECT_EQ(board::control_mode_from_value(2.0F), board::ControlMode::Torque);
  EXPECT_EQ(board::control_mode_from_value(-0.0F), board::ControlMode::Disabled);
  EXPECT_FALSE(board::led_pattern_from_value(4.0F).has_value());
}
#endif

TEST(ValueTable, EveryFlagBitMatchesThePythonTable) {
  const auto sets = rows_by_set("bit");
  std::set<std::string, std::less<>> seen;
  board::for_each_bitset([&](std::string_view set, const auto& bits, const auto& infos) {
    SCOPED_TRACE("bitset " + std::string(set));
    seen.insert(std::string(set));
    const auto found = sets.find(set);
    ASSERT_NE(found, sets.end()) << "not in the Python table";
    ASSERT_EQ(infos.size(), found->second.size());
    ASSERT_EQ(bits.size(), infos.size());
    for (const ValueRow& row : found->second) {
      SCOPED_TRACE("bit " + row.name);
      const board::FlagInfo* info = nullptr;
      for (const board::FlagInfo& candidate : infos) {
        if (candidate.name == row.name) info = &candidate;
      }
      ASSERT_NE(info, nullptr) << "not in the header";
      EXPECT_EQ(info->bit, std::stoul(row.number));
      if (row.emcy.empty()) {
        EXPECT_FALSE(info->emcy.has_value());
      } else {
        ASSERT_TRUE(info->emcy.has_value());
        EXPECT_EQ(board::info(*info->emcy).name, row.emcy);
      }
      if (row.about.empty()) {
        EXPECT_FALSE(info->about_index.has_value());
      } else {
        EXPECT_EQ(info->about_index, std::optional(static_cast<std::uint16_t>(std::stoul(row.about, nullptr, 16))));
      }
    }
  });
  EXPECT_EQ(seen, keys(sets)) << "the header and the Python table list different bitsets";
}

TEST(ValueTable, TypedBitsMatchTheirInfoLowestFirst) {
  board::for_each_bitset([](std::string_view set, const auto& bits, const auto& infos) {
    SCOPED_TRACE("bitset " + std::string(set));
    ASSERT_EQ(bits.size(), infos.size());
    std::uint32_t seen = 0;
    for (std::size_t i = 0; i < bits.size(); ++i) {
      EXPECT_EQ(to_string(bits[i]), infos[i].name);
      EXPECT_EQ(static_cast<unsigned>(bits[i]), infos[i].bit);
      EXPECT_EQ(mask(bits[i]), infos[i].mask());
      EXPECT_LT(infos[i].bit, 24U) << infos[i].name << ": a float holds integers exactly up to 2^24";
      EXPECT_EQ(seen & infos[i].mask(), 0U) << infos[i].name << ": bit used twice";
      if (i > 0) {
        EXPECT_LT(infos[i - 1].bit, infos[i].bit);
      }
      seen |= infos[i].mask();
    }
  });
  std::uint32_t all = 0;
  for (const board::FlagInfo& info : board::kFaultFlagsInfo) all |= info.mask();
  EXPECT_EQ(board::kFaultFlagsMask, all);
}

TEST(ValueTable, RecorderMatchesThePythonTable) {
  const auto rows = read_value_rows("recorder");
  ASSERT_EQ(rows.size(), 4U);
  std::map<std::string, std::uint32_t, std::less<>> settings;
  for (const ValueRow& row : rows) settings[row.name] = static_cast<std::uint32_t>(std::stoul(row.number, nullptr, 0));
  EXPECT_EQ(board::kRecorder.index, settings["index"]);
  EXPECT_EQ(board::kRecorder.max_channels, settings["channels"]);
  EXPECT_EQ(board::kRecorder.buffer_values, settings["buffer_values"]);
  EXPECT_EQ(board::kRecorder.default_samples, settings["default_samples"]);
  EXPECT_EQ(board::recorder::kState, board::kRecorder.index);
  EXPECT_EQ(board::recorder::kData, board::kRecorder.index + 6);
}

}  // namespace

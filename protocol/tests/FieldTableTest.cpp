// C++ and Python agree on every field: board::kFields (generated header) must equal
// field_vectors.csv, which the generator writes straight from the parsed board.toml.
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "board/fields.hpp"

namespace {

struct CsvRow {
  std::string name, index, unit, kind, access, min, max, default_value, stored;
};

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> cells;
  std::stringstream stream(line);
  std::string cell;
  while (std::getline(stream, cell, ',')) cells.push_back(cell);
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
  std::set<std::uint16_t> seen;
  for (const auto& field : board::kFields) {
    EXPECT_GE(field.index, 0x2000U) << field.name;
    EXPECT_LE(field.index, 0x5FFFU) << field.name;
    EXPECT_TRUE(seen.insert(field.index).second) << "duplicate index of " << field.name;
  }
  for (const auto& io : board::kHilInputs) EXPECT_TRUE(seen.insert(io.index).second) << io.name;
  for (const auto& io : board::kHilOutputs) EXPECT_TRUE(seen.insert(io.index).second) << io.name;
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

}  // namespace

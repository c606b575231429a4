// Test doubles and a fixture that scripts exact CAN frames against a Node on a MemoryPort.
#pragma once

#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <initializer_list>
#include <vector>

#include "MemoryPort.hpp"
#include "Node.hpp"
#include "ObjectTables.hpp"

namespace co::test {

// A board that stores fields in an array and can be told to refuse writes to some of them.
class FakeBoard final : public FieldAccess {
 public:
  FakeBoard();
  float read(board::FieldId id) override { return values[index(id)]; }
  WriteResult write(board::FieldId id, float value) override;

  static std::size_t index(board::FieldId id) { return static_cast<std::size_t>(id); }
  std::array<float, board::kFieldCount> values{};
  std::array<bool, board::kFieldCount> refuse{};
  std::array<std::uint32_t, board::kFieldCount> writes{};
};

class FakeHil final : public HilIo {
 public:
  void write_input(board::HilInputId id, std::int32_t raw) override {
    inputs[static_cast<std::size_t>(id)] = raw;
    ++input_writes;
  }
  std::int32_t read_output(board::HilOutputId id) override {
    return outputs[static_cast<std::size_t>(id)];
  }
  std::array<std::int32_t, board::kHilInputCount> inputs{};
  std::array<std::int32_t, board::kHilOutputCount> outputs{};
  std::uint32_t input_writes = 0;
};

class MemoryStorage final : public ParameterStorage {
 public:
  bool save(std::span<const std::byte> image) override;
  std::size_t load(std::span<std::byte> buffer) override;
  std::vector<std::byte> bytes;
  bool fail_saves = false;
  std::uint32_t saves = 0;
};

// co::ProgramStore in memory (program download tests), with what it was given.
class MemoryProgramStore final : public ProgramStore {
 public:
  bool open_staging() override {
    staging.clear();
    open = true;
    return true;
  }
  bool write_staging(std::span<const std::uint8_t> bytes) override {
    staging.insert(staging.end(), bytes.begin(), bytes.end());
    return !fail_writes;
  }
  bool commit_staging() override {
    kept = staging;
    open = false;
    return true;
  }
  void discard_staging() override {
    staging.clear();
    kept.clear();
    open = false;
    ++discards;
  }
  std::uint32_t running_image_crc32() override { return 0xC0FF'EE00u; }

  std::vector<std::uint8_t> staging;
  std::vector<std::uint8_t> kept;
  bool open = false;
  bool fail_writes = false;
  int discards = 0;
};

CanFrame make_frame(std::uint32_t id, std::initializer_list<std::uint8_t> data);
// The 8 data bytes of an SDO abort frame.
std::array<std::uint8_t, 8> abort_data(std::uint16_t index, std::uint8_t sub, SdoAbort code);
std::uint16_t index_of(board::FieldId id);
std::uint16_t index_of(board::HilInputId id);
std::uint16_t index_of(board::HilOutputId id);
// The master the tests play (node 1) and its heartbeat's COB-ID.
inline constexpr std::uint8_t kMasterId = 0x01;
inline constexpr std::uint32_t kMasterHeartbeat = cia301::cob_id(cia301::FunctionCode::Heartbeat, kMasterId);
// Bit 31 of a COB-ID entry (PDO, SYNC, EMCY): not valid.
inline constexpr std::uint32_t kInvalid = tables::kPdoInvalidBit;

std::array<std::uint8_t, 4> le32(std::uint32_t v);
std::uint32_t float_bits(float v);

class NodeTest : public ::testing::Test {
 protected:
  static constexpr std::uint8_t kNodeId = 0x10;
  static constexpr std::uint32_t kSdoRx = cia301::cob_id(cia301::FunctionCode::SdoRequest, kNodeId);
  static constexpr std::uint32_t kSdoTx = cia301::cob_id(cia301::FunctionCode::SdoResponse, kNodeId);
  static constexpr std::uint32_t kEmcy = cia301::cob_id(cia301::FunctionCode::SyncEmcy, kNodeId);
  static constexpr std::uint32_t kHeartbeat = cia301::cob_id(cia301::FunctionCode::Heartbeat, kNodeId);
  static constexpr std::uint32_t kSerial = 0x1234'5678;

  void SetUp() override;

  ProcessResult receive(std::uint32_t id, std::initializer_list<std::uint8_t> data);
  ProcessResult receive(const CanFrame& frame);
  void nmt(NmtCommand command, std::uint8_t target = kNodeId);
  void sync();
  void advance_us(std::uint32_t us);  // moves the clock and polls

  // Pops the next frame the node sent; fails the test when there is none.
  CanFrame next_sent();
  std::vector<CanFrame> all_sent();

  // Sends one SDO request, expects exactly one response on 0x580+id and returns its data.
  std::array<std::uint8_t, 8> sdo(std::array<std::uint8_t, 8> request);
  // Expedited download of `size` bytes; returns SdoAbort::None on success or the abort code.
  SdoAbort download(std::uint16_t index, std::uint8_t sub, std::uint32_t value, std::uint8_t size);
  SdoAbort download_float(std::uint16_t index, float value);
  // Expedited upload; fails the test on an abort or a segmented answer.
  std::uint32_t upload(std::uint16_t index, std::uint8_t sub);
  // Upload returning the abort code (None on success).
  SdoAbort upload_abort(std::uint16_t index, std::uint8_t sub);

  MemoryPort port;
  FakeBoard fields;
  FakeHil hil;
  MemoryStorage storage;
  Recorder recorder;  // served by the node (set in SetUp); tests feed it samples themselves
  Node node{kNodeId, port, fields, hil, storage, kSerial};
  std::uint32_t now_us = 1'000;
};

}  // namespace co::test

// The engine and the generated CiA 301 rules (board/cia301.hpp, from boardproto.cia301) agree:
// every abort the SDO server answers is a generated code with its text, and the node's frames
// go where the generated connection set and EMCY layout say.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <utility>
#include <vector>

#include "NodeTestSupport.hpp"
#include "board/cia301.hpp"

namespace co::test {
namespace {

using cia301::FunctionCode;

constexpr bool aborts_are_sorted_and_unique() {
  for (std::size_t n = 1; n < cia301::kSdoAborts.size(); ++n) {
    if (to_code(cia301::kSdoAborts[n - 1].abort) >= to_code(cia301::kSdoAborts[n].abort)) return false;
  }
  return true;
}

static_assert(aborts_are_sorted_and_unique());
static_assert(cia301::text(SdoAbort::None).empty(), "success is no abort");
static_assert(!cia301::text(SdoAbort::ResourceNotAvailable).empty());
static_assert(!cia301::text(SdoAbort::LocalControl).empty());

bool is_generated_abort(std::uint32_t code) {
  return std::any_of(cia301::kSdoAborts.begin(), cia301::kSdoAborts.end(),
                     [code](const cia301::SdoAbortInfo& info) { return to_code(info.abort) == code; });
}

class Cia301Test : public NodeTest {};

TEST_F(Cia301Test, EveryGeneratedAbortHasAText) {
  for (const cia301::SdoAbortInfo& info : cia301::kSdoAborts) {
    EXPECT_NE(info.abort, SdoAbort::None);
    EXPECT_FALSE(info.text.empty()) << std::hex << to_code(info.abort);
    EXPECT_EQ(cia301::text(info.abort), info.text);
  }
}

TEST_F(Cia301Test, EveryAbortTheServerAnswersIsAGeneratedCodeOnTheWire) {
  const std::uint16_t read_only = index_of(board::FieldId::motor_position);
  const std::uint16_t parameter = index_of(board::FieldId::velocity_kp);
  // Requests the server refuses, each a different way; the answer is an abort frame whose code
  // (bytes 4..7, little-endian) must be one of the generated list.
  const std::vector<std::pair<std::array<std::uint8_t, 8>, SdoAbort>> refused = {
      {{0x40, 0x34, 0x12, 0x00, 0, 0, 0, 0}, SdoAbort::ObjectDoesNotExist},
      {{0x23, static_cast<std::uint8_t>(read_only), static_cast<std::uint8_t>(read_only >> 8), 0, 0, 0, 0, 0},
       SdoAbort::ReadOnly},
      {{0x40, static_cast<std::uint8_t>(parameter), static_cast<std::uint8_t>(parameter >> 8), 9, 0, 0, 0, 0},
       SdoAbort::SubIndexDoesNotExist},
      {{0x2F, static_cast<std::uint8_t>(parameter), static_cast<std::uint8_t>(parameter >> 8), 0, 1, 0, 0, 0},
       SdoAbort::LengthTooLow},  // 1 byte for a REAL32
      {{0xE0, 0x00, 0x10, 0x00, 0, 0, 0, 0}, SdoAbort::CommandSpecifierInvalid},
  };
  for (const auto& [request, expected] : refused) {
    const std::array<std::uint8_t, 8> answer = sdo(request);
    const std::uint32_t code = static_cast<std::uint32_t>(answer[4]) | (std::uint32_t{answer[5]} << 8) |
                               (std::uint32_t{answer[6]} << 16) | (std::uint32_t{answer[7]} << 24);
    EXPECT_EQ(code, to_code(expected)) << cia301::text(expected);
    EXPECT_TRUE(is_generated_abort(code)) << std::hex << code;
  }
}

TEST_F(Cia301Test, BootUpAndHeartbeatGoOnTheGeneratedErrorControlId) {
  node.start(now_us);
  EXPECT_EQ(next_sent(), make_frame(cia301::cob_id(FunctionCode::Heartbeat, kNodeId),
                                    {static_cast<std::uint8_t>(cia301::NmtState::Initialising)}));
  ASSERT_EQ(download(0x1017, 0, 10, 2), SdoAbort::None);  // heartbeat every 10 ms
  advance_us(10'000);
  const CanFrame heartbeat = next_sent();
  EXPECT_EQ(heartbeat.id, cia301::cob_id(FunctionCode::Heartbeat, kNodeId));
  EXPECT_EQ(heartbeat.data[0] & cia301::kHeartbeatStateMask,
            static_cast<std::uint8_t>(cia301::NmtState::PreOperational));
}

TEST_F(Cia301Test, EmcyFramesFollowTheGeneratedLayout) {
  namespace layout = cia301::emcy_layout;
  ASSERT_TRUE(node.report_emcy(0x1234, error_register::kVoltage, {1, 2, 3, 4, 5}));
  const CanFrame emcy = next_sent();
  EXPECT_EQ(emcy.id, cia301::cob_id(FunctionCode::SyncEmcy, kNodeId));
  ASSERT_EQ(emcy.len, layout::kFrameBytes);
  EXPECT_EQ(emcy.data[layout::kErrorCodeOffset], 0x34);
  EXPECT_EQ(emcy.data[layout::kErrorCodeOffset + 1], 0x12);
  EXPECT_EQ(emcy.data[layout::kErrorRegisterOffset] & error_register::kVoltage, error_register::kVoltage);
  for (std::size_t n = 0; n < layout::kManufacturerBytes; ++n) {
    EXPECT_EQ(emcy.data[layout::kManufacturerOffset + n], n + 1);
  }
  EXPECT_EQ(upload(0x1014, 0), cia301::cob_id(FunctionCode::SyncEmcy, kNodeId));  // COB-ID EMCY
}

}  // namespace
}  // namespace co::test

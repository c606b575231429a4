// Victim of FileParameterStorageCrashTest: stores parameter sets into a file in a tight loop, the
// way the firmware does, until it is killed. Test-only (built with HIL_TESTS).
//
// Usage: parameter-store-crash-child PARAMS_FILE
//
// Start-up loads PARAMS_FILE through co::Node::start() and linuxhw::FileParameterStorage, as
// joint-firmware does with --params. Then it writes "next G\n" on stdout, G being the generation
// (ParameterStoreCrashGeneration.hpp) after the loaded one, or 1 when nothing is stored, and
// stores generations G, G+1, ... each by an expedited SDO download of "save" to 0x1010, exactly
// what a bus master sends. It never stops by itself.
//
// Exit status: 2 bad usage; 3 the stored file was rejected or not one whole generation; 4 a
// store was refused (the message names the storage error). The parent's death kills it too.
#include <sys/prctl.h>
#include <unistd.h>

#include <array>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <string>

#include "FileParameterStorage.hpp"
#include "MemoryPort.hpp"
#include "Node.hpp"
#include "ParameterStoreCrashGeneration.hpp"

namespace {

namespace store_crash = linuxhw::store_crash;

constexpr std::uint8_t kNodeId = 0x10;

// The board as far as the node sees it: every field in an array, starting at its default.
class ArrayBoard final : public co::FieldAccess {
 public:
  ArrayBoard() {
    for (std::size_t i = 0; i < board::kFieldCount; ++i) values[i] = board::kFields[i].default_value;
  }
  float read(board::FieldId id) override { return values[static_cast<std::size_t>(id)]; }
  co::WriteResult write(board::FieldId id, float value) override {
    values[static_cast<std::size_t>(id)] = value;
    return co::WriteResult::Accepted;
  }
  float& operator[](board::FieldId id) { return values[static_cast<std::size_t>(id)]; }

  std::array<float, board::kFieldCount> values{};
};

class NoHil final : public co::HilIo {
 public:
  void write_input(board::HilInputId, std::int32_t) override {}
  std::int32_t read_output(board::HilOutputId) override { return 0; }
};

// The generation `fields` hold when every stored field agrees with it.
bool whole_generation(ArrayBoard& fields, std::uint32_t& generation) {
  const auto named = store_crash::generation_of(fields[store_crash::kGenerationLow],
                                                fields[store_crash::kGenerationHigh]);
  if (!named) return false;
  for (std::size_t i = 0; i < board::kFieldCount; ++i) {
    const auto id = static_cast<board::FieldId>(i);
    if (board::kFields[i].stored && fields[id] != store_crash::value_in_generation(id, *named)) {
      return false;
    }
  }
  generation = *named;
  return true;
}

// Drains what the node sent; true when it contains the SDO "download done" answer.
bool store_confirmed(co::MemoryPort& port) {
  bool confirmed = false;
  co::CanFrame frame;
  while (port.pop_sent(frame)) {
    if (frame.id == cia301::cob_id(cia301::FunctionCode::SdoResponse, kNodeId) && frame.len == 8 && frame.data[0] == 0x60 &&
        frame.data[1] == 0x10 && frame.data[2] == 0x10 && frame.data[3] == 0x01) {
      confirmed = true;
    }
  }
  return confirmed;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s PARAMS_FILE\n", argv[0]);
    return 2;
  }
  // Never outlive the test that spawned us (a failed assertion there skips the kill).
  const pid_t parent = ::getppid();
  if (::prctl(PR_SET_PDEATHSIG, SIGKILL) != 0 || ::getppid() != parent) return 0;

  linuxhw::FileParameterStorage storage(argv[1]);
  co::MemoryPort port;
  ArrayBoard fields;
  NoHil hil;
  co::Node node(kNodeId, port, fields, hil, storage);
  node.start(0);

  std::uint32_t generation = 1;
  switch (node.parameter_load()) {
    case co::ParameterLoad::Loaded:
      if (!whole_generation(fields, generation)) {
        std::fprintf(stderr, "%s: loaded parameters are not one whole generation\n", argv[1]);
        return 3;
      }
      ++generation;
      break;
    case co::ParameterLoad::NothingStored: break;
    case co::ParameterLoad::Rejected:
    case co::ParameterLoad::NotAttempted:
      std::fprintf(stderr, "%s: stored parameters rejected (%s)\n", argv[1],
                   storage.last_error().c_str());
      return 3;
  }
  const std::string ready = "next " + std::to_string(generation) + "\n";
  if (::write(STDOUT_FILENO, ready.data(), ready.size()) != static_cast<ssize_t>(ready.size())) {
    return 2;
  }

  co::CanFrame save;  // SDO expedited download, 4 bytes, 0x1010 sub 1 = "save"
  save.id = cia301::cob_id(cia301::FunctionCode::SdoRequest, kNodeId);
  save.len = 8;
  save.data = {0x23, 0x10, 0x10, 0x01, 's', 'a', 'v', 'e'};
  (void)store_confirmed(port);  // the boot-up message
  for (std::uint32_t now_us = 0;; ++generation, ++now_us) {
    for (std::size_t i = 0; i < board::kFieldCount; ++i) {
      const auto id = static_cast<board::FieldId>(i);
      if (board::kFields[i].stored) fields[id] = store_crash::value_in_generation(id, generation);
    }
    node.process(save, now_us);
    if (!store_confirmed(port)) {
      std::fprintf(stderr, "store of generation %u refused: %s\n", generation,
                   storage.last_error().c_str());
      return 4;
    }
  }
}

// FileParameterStorage under real SIGKILLs. Each iteration spawns ParameterStoreCrashChild, which
// loads the parameter file and then stores whole parameter generations in a tight loop through
// co::Node (0x1010 "save" over SDO) and FileParameterStorage, exactly as the firmware does; the
// test kills it with SIGKILL after a seeded-random delay and loads the file back through
// co::Node::start(), the firmware's start-up path. After every kill the file must either not
// exist yet (no store has completed so far) or load as exactly one whole generation, never older
// than the one loaded after the previous kill, and the directory must hold nothing else once
// loaded. Only where the kill lands depends on timing; nothing asserts a duration.
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <stdlib.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "../../canopen/NodeTestSupport.hpp"
#include "FileParameterStorage.hpp"
#include "ParameterStoreCrashGeneration.hpp"

extern char** environ;

namespace linuxhw {
namespace {

namespace fs = std::filesystem;
using co::test::FakeBoard;

constexpr const char* kChild = PARAMETER_STORE_CRASH_CHILD;
constexpr int kIterations = 240;
constexpr std::uint32_t kSeed = 0x5EED'0011;
// One kill in this many comes at a random moment after the spawn, without waiting for the child
// to report it is about to store: it lands in exec, sanitizer start-up, the load or the first
// stores. The others wait for that report, then up to a few stores' worth of time (a store with
// its two fsyncs takes milliseconds here), so they land anywhere inside the store loop.
constexpr int kEarlyKillOneIn = 6;
constexpr int kEarlyKillMaxDelayUs = 25'000;
constexpr int kStoreLoopMaxDelayUs = 6'000;

// A spawned child with its stdout on a pipe; killed and reaped if still running at destruction.
class Child {
 public:
  explicit Child(const fs::path& params) {
    int out[2];
    if (::pipe2(out, O_CLOEXEC) != 0) return;
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, out[1], STDOUT_FILENO);  // clears O_CLOEXEC
    const std::string params_arg = params.string();
    char* argv[] = {const_cast<char*>(kChild), const_cast<char*>(params_arg.c_str()), nullptr};
    if (::posix_spawn(&pid_, kChild, &actions, nullptr, argv, environ) != 0) pid_ = -1;
    posix_spawn_file_actions_destroy(&actions);
    ::close(out[1]);
    out_ = out[0];
  }
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;
  ~Child() {
    if (pid_ > 0) (void)kill_and_wait();
    if (out_ >= 0) ::close(out_);
  }

  bool spawned() const { return pid_ > 0; }

  // The generation the child is about to store first ("next G" line); nullopt if it died first.
  std::optional<std::uint32_t> wait_until_storing() {
    std::string line;
    char c = 0;
    while (true) {
      const ssize_t n = ::read(out_, &c, 1);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) return std::nullopt;
      if (c == '\n') break;
      line += c;
    }
    unsigned long generation = 0;
    if (std::sscanf(line.c_str(), "next %lu", &generation) != 1) return std::nullopt;
    return static_cast<std::uint32_t>(generation);
  }

  // SIGKILL, then the wait status.
  int kill_and_wait() {
    (void)::kill(pid_, SIGKILL);
    int status = 0;
    while (::waitpid(pid_, &status, 0) < 0 && errno == EINTR) {
    }
    pid_ = -1;
    return status;
  }

 private:
  pid_t pid_ = -1;
  int out_ = -1;
};

std::string describe(int status) {
  if (WIFEXITED(status)) return "exited with status " + std::to_string(WEXITSTATUS(status));
  if (WIFSIGNALED(status)) return "killed by signal " + std::to_string(WTERMSIG(status));
  return "wait status " + std::to_string(status);
}

class FileParameterStorageCrashTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::temp_directory_path() / "fw-params-crash-XXXXXX").string();
    ASSERT_NE(::mkdtemp(pattern.data()), nullptr);
    dir = pattern;
    path = dir / "parameters.bin";
    temp_path = path.string() + ".tmp";
  }
  void TearDown() override { fs::remove_all(dir); }

  // Loads `path` as joint-firmware does at start-up. Sets `generation` to the whole generation
  // it holds, or nullopt when nothing is stored; fails the test on anything else.
  void load_as_firmware(std::optional<std::uint32_t>& generation) {
    FileParameterStorage storage(path.string());
    co::MemoryPort port;
    FakeBoard fields;
    co::test::FakeHil hil;
    co::Node node(0x10, port, fields, hil, storage);
    node.start(0);
    const auto value = [&](board::FieldId id) { return fields.values[FakeBoard::index(id)]; };
    switch (node.parameter_load()) {
      case co::ParameterLoad::NothingStored:
        ASSERT_FALSE(fs::exists(path)) << "an existing parameter file loaded as nothing stored";
        generation.reset();
        return;
      case co::ParameterLoad::Loaded: break;
      case co::ParameterLoad::Rejected:
      case co::ParameterLoad::NotAttempted:
        FAIL() << "parameter file rejected after a kill: " << storage.last_error();
    }
    generation = store_crash::generation_of(value(store_crash::kGenerationLow),
                                            value(store_crash::kGenerationHigh));
    ASSERT_TRUE(generation) << "loaded generation carriers are not a generation: "
                            << value(store_crash::kGenerationLow) << ", "
                            << value(store_crash::kGenerationHigh);
    for (std::size_t i = 0; i < board::kFieldCount; ++i) {
      const auto id = static_cast<board::FieldId>(i);
      if (!board::kFields[i].stored) continue;
      ASSERT_EQ(value(id), store_crash::value_in_generation(id, *generation))
          << board::kFields[i].name << " is not from generation " << *generation
          << ": the loaded set is torn or mixed";
    }
  }

  std::vector<std::string> directory_names() const {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(dir)) names.push_back(entry.path().filename());
    return names;
  }

  fs::path dir;
  fs::path path;
  std::string temp_path;
};

TEST_F(FileParameterStorageCrashTest, KillDuringStoresAlwaysLeavesOneWholeGeneration) {
  std::mt19937 random(kSeed);
  std::uniform_int_distribution<int> pick_mode(0, kEarlyKillOneIn - 1);
  std::uniform_int_distribution<int> early_delay_us(0, kEarlyKillMaxDelayUs);
  std::uniform_int_distribution<int> store_loop_delay_us(0, kStoreLoopMaxDelayUs);

  const auto started = std::chrono::steady_clock::now();
  std::optional<std::uint32_t> last;  // generation loaded after the previous kill
  int early_kills = 0;
  int kills_with_temp_empty = 0;   // temporary file created, image not written yet
  int kills_with_temp_filled = 0;  // image written, not renamed yet (the fsync window)
  int kills_after_progress = 0;    // the file holds a newer generation than before the kill
  for (int iteration = 0; iteration < kIterations; ++iteration) {
    SCOPED_TRACE(::testing::Message() << "iteration " << iteration << ", seed 0x" << std::hex
                                        << kSeed);
    const bool early = pick_mode(random) == 0;
    const int delay_us = early ? early_delay_us(random) : store_loop_delay_us(random);

    Child child(path);
    ASSERT_TRUE(child.spawned()) << "cannot spawn " << kChild;
    if (!early) {
      const auto first = child.wait_until_storing();
      ASSERT_TRUE(first) << "the child died before storing: " << describe(child.kill_and_wait());
      // It continues from what it loaded itself, through the same code.
      ASSERT_EQ(*first, last ? *last + 1 : 1u);
    }
    std::this_thread::sleep_for(std::chrono::microseconds(delay_us));
    const int status = child.kill_and_wait();
    ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL)
        << "the child stopped on its own (its stderr says why): " << describe(status);
    early_kills += early ? 1 : 0;

    std::error_code error;
    if (fs::exists(temp_path, error)) {
      ++(fs::file_size(temp_path, error) == 0 ? kills_with_temp_empty : kills_with_temp_filled);
    }

    std::optional<std::uint32_t> loaded;
    ASSERT_NO_FATAL_FAILURE(load_as_firmware(loaded));
    if (last) {
      ASSERT_TRUE(loaded) << "generation " << *last << " was stored and is gone";
      ASSERT_GE(*loaded, *last) << "the file went back to an older generation";
    }
    kills_after_progress += loaded && (!last || *loaded > *last) ? 1 : 0;
    last = loaded;

    // The load removed any leftover of the killed store: only the parameter file remains.
    const auto names = directory_names();
    ASSERT_EQ(names, loaded ? std::vector<std::string>{"parameters.bin"} : std::vector<std::string>{});
  }
  const auto elapsed_ms = std::chrono::duration_cast<std::chrono::milliseconds>(
                              std::chrono::steady_clock::now() - started)
                              .count();

  const int kills_mid_store = kills_with_temp_empty + kills_with_temp_filled;
  std::printf(
      "[ figures  ] %d SIGKILLs (seed 0x%X, %d before the store loop was reached for sure), "
      "%d mid-store with the temporary file present (%d still empty, %d written, not renamed), "
      "%d after at least one new store; %u generations stored in all; %lld ms\n",
      kIterations, kSeed, early_kills, kills_mid_store, kills_with_temp_empty,
      kills_with_temp_filled, kills_after_progress, last.value_or(0),
      static_cast<long long>(elapsed_ms));
  RecordProperty("kills", kIterations);
  RecordProperty("kills_mid_store", kills_mid_store);
  RecordProperty("generations_stored", static_cast<int>(last.value_or(0)));

  // Without these the loop above proved nothing: no store completed, or no kill hit one.
  EXPECT_TRUE(last) << "no store ever completed before a kill";
  EXPECT_GT(kills_mid_store, 0) << "no kill landed while a store was in progress";
}

}  // namespace
}  // namespace linuxhw

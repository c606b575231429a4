// Platform part of the unit-test images on qemu's mps2-an386: newlib's rdimon library does the
// I/O over Arm semihosting (the test output goes to qemu's stdout, a file the tests read is the
// host's, exit() ends qemu with the status), and main() runs googletest with the command line
// qemu was given (-append: run-test-image's arguments, e.g. --gtest_filter=...). Only the test images link this; they may use
// newlib's heap (googletest needs one), the firmware image has none.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <array>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstdlib>

extern "C" {
void initialise_monitor_handles();

void hil_platform_init() { initialise_monitor_handles(); }

// googletest's XML report would make its folder first: semihosting cannot make folders (nor
// tell one from a file), so the images report through their output and exit status only.
int mkdir(const char*, mode_t) {
  errno = ENOSYS;
  return -1;
}

[[noreturn]] void hil_fault(const char* what) {
  std::fprintf(stderr, "cortex-m test image: %s\n", what);
  std::_Exit(3);
}
}

namespace {

// SYS_GET_CMDLINE: the image's path and qemu's -append text, one line.
bool semihosting_command_line(std::array<char, 1024>& text) {
  struct {
    char* buffer;
    std::uint32_t length;
  } block{text.data(), text.size() - 1};
  register std::uint32_t operation asm("r0") = 0x15;
  register void* argument asm("r1") = &block;
  asm volatile("bkpt 0xab" : "+r"(operation) : "r"(argument) : "memory");
  return operation == 0;
}

}  // namespace

int main() {
  static std::array<char, 1024> text{};
  static std::array<char*, 16> argv{};
  int argc = 0;
  if (semihosting_command_line(text)) {
    // Split at spaces (no quoting: the arguments run-test-image passes have none).
    for (char* c = text.data(); *c != '\0' && argc < static_cast<int>(argv.size()) - 1;) {
      while (*c == ' ') *c++ = '\0';
      if (*c == '\0') break;
      argv[static_cast<std::size_t>(argc++)] = c;
      while (*c != '\0' && *c != ' ') ++c;
    }
  }
  static char name[] = "test-image";
  if (argc == 0) argv[static_cast<std::size_t>(argc++)] = name;
  testing::InitGoogleTest(&argc, argv.data());
  return RUN_ALL_TESTS();
}

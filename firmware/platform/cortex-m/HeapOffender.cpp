// Built only by the test cortex_m.firmware_link_rejects_malloc: a firmware image that calls
// malloc must fail to link (CMakeLists.txt's wraps), or "no heap" would be an unchecked claim.
#include <cstdlib>

extern "C" void hil_platform_init() {}
extern "C" [[noreturn]] void hil_fault(const char*) {
  for (;;) {
  }
}

int main() {
  void* block = std::malloc(16);
  return block != nullptr ? 0 : 1;
}

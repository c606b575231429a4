// The tiny tree's unit tests: one per argument, so ctest names the one that fails.
#include <cstring>

#include "Clamp.hpp"

int main(int argc, char** argv) {
  if (argc < 2) return 2;
  if (std::strcmp(argv[1], "limits") == 0) {
    return clamp_duty(2.0F, 0.5F) == 0.5F && clamp_duty(-2.0F, 0.5F) == -0.5F ? 0 : 1;
  }
  return clamp_duty(0.25F, 0.5F) == 0.25F ? 0 : 1;
}

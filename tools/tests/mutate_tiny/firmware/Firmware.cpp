// The tiny tree's "firmware": what a mutant's scenarios would start. It prints its build type
// (NDEBUG: the release configuration the scenarios' firmware is built in) and a product value.
#include <cstdio>

int unused_in_tests(int value);

int main() {
#ifdef NDEBUG
  std::printf("release %d\n", unused_in_tests(1));
#else
  std::printf("debug %d\n", unused_in_tests(1));
#endif
  return 0;
}

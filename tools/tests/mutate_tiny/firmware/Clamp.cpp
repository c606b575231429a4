// The product code of the tiny tree: a duty limit as the firmware's Motor has one.
#include "Clamp.hpp"

float clamp_duty(float duty, float limit) {
  if (duty > limit) return limit;
  if (duty < -limit) return -limit;
  return duty;
}

int unused_in_tests(int value) {
  return value * 3;
}

int scaled(const int value, int factor) {
  factor = factor + value;
  return factor;
}

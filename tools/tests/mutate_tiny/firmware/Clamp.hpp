#pragma once
float clamp_duty(float duty, float limit);
int unused_in_tests(int value);

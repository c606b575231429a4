// The one test of cm_runner_check: it fails, so run-test-image must end non-zero (ctest expects
// that, WILL_FAIL); a runner that lost the status would pass every image.
#include <gtest/gtest.h>

TEST(CortexMRunner, AFailingTestEndsTheImageWithAFailureStatus) { ADD_FAILURE() << "expected: checks the runner"; }

// The suite's main: GoogleTest's, except that a run in which every selected test skipped (a
// backend that cannot run on this machine) exits with 77, which ctest reports as skipped
// rather than passed. A run with any failure still fails.
#include <gtest/gtest.h>

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  const int result = RUN_ALL_TESTS();
  const ::testing::UnitTest& u = *::testing::UnitTest::GetInstance();
  if (result == 0 && u.skipped_test_count() > 0 && u.successful_test_count() == 0 && u.failed_test_count() == 0)
    return 77;
  return result;
}

// The handler VISCD_ASSERT reports to (viscd/assert.hpp).
#include <cstdio>

#include "viscd/assert.hpp"

namespace viscd {

namespace {
bool default_assert_handler(const char* expr, const char* message, const char* file, int line) {
  std::fprintf(stderr, "%s:%d: viscd assertion failed: %s (%s)\n", file, line, expr, message);
  return false;
}
AssertHandler g_assert_handler = default_assert_handler;
}  // namespace

AssertHandler set_assert_handler(AssertHandler handler) {
  AssertHandler old = g_assert_handler;
  g_assert_handler = handler ? handler : default_assert_handler;
  return old;
}

bool assert_failed(const char* expr, const char* message, const char* file, int line) {
  return g_assert_handler(expr, message, file, line);
}

}  // namespace viscd

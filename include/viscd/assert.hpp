#pragma once
/// \file assert.hpp
/// VISCD_ASSERT(cond, msg): checks a precondition or invariant. On in Debug and RelWithDebInfo
/// (and whenever VISCD_ENABLE_ASSERTS is defined), off in Release. A failed assert calls the
/// handler, which by default prints file, line, condition and message, then aborts.

namespace viscd {

/// Called on a failed assert. Return true to continue past it (tests), false to abort.
using AssertHandler = bool (*)(const char* expr, const char* message, const char* file, int line);
/// Replaces the handler; returns the previous one. Not thread-safe: set it once at start-up.
AssertHandler set_assert_handler(AssertHandler handler);
/// Internal: reports a failure through the current handler.
bool assert_failed(const char* expr, const char* message, const char* file, int line);

}  // namespace viscd

#if !defined(VISCD_ENABLE_ASSERTS) && (!defined(NDEBUG) || defined(VISCD_RELWITHDEBINFO))
#define VISCD_ENABLE_ASSERTS
#endif

#ifdef VISCD_ENABLE_ASSERTS
#define VISCD_ASSERT(cond, msg)                                                               \
  do {                                                                                        \
    if (!(cond) && !::viscd::assert_failed(#cond, msg, __FILE__, __LINE__)) __builtin_trap(); \
  } while (false)
#else
#define VISCD_ASSERT(cond, msg) ((void)0)
#endif
